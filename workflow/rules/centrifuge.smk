# The precision centrifuge (docs/centrifuge-model.md): its Monte Carlo sweep runs through the
# generic rules (montecarlo.smk); here its own stages, all under results/centrifuge/:
#   single/      the single run behind Table 2 and the convergence figure
#   tables/      Table 2 (one run, Monte Carlo) and the summary; figures/; report.md
#   design/      GA schemes (ga_*.yaml, read by the sweep) and the design studies
# `snakemake --cores 2 design_all` builds the full design report (design/report.md).
from platcal.rigs.centrifuge.design import design_config
from platcal.rigs.centrifuge.compare_cells import compare_cells, compare_levels
from platcal.rigs.centrifuge.compare_cells import level_params as compare_level_params
from platcal.rigs.centrifuge.report import COMPARE_FIGURES, COMPARE_TABLES, FIGURES, TABLES
from platcal.rigs.centrifuge.study import (
    DESIGN_KEYS,
    NO_DESIGN,
    design_targets,
    single_params,
)

CEN = MC_CONFIG.get("centrifuge")  # None: the centrifuge is not in the study index
CEN_DESIGN = NO_DESIGN if CEN is None else checked("centrifuge", design_config, CEN)
GA_CRITERIA = ["ga_" + c for c in CEN_DESIGN["study"]["criteria"]]
GA_NPOS = [
    "ga_" + c if n == CEN_DESIGN["positions"] else "ga_%s_n%d" % (c, n)
    for c in CEN_DESIGN["study"]["n_criteria"]
    for n in CEN_DESIGN["study"]["n_positions"]
]
CENTRIFUGE_TARGETS = (
    []
    if CEN is None
    else [
        *expand(
            "results/centrifuge/tables/{table}.{ext}",
            table=TABLES,
            ext=["csv", "md", "html"],
        ),
        *expand("results/centrifuge/figures/{f}", f=FIGURES.values()),
        *expand("results/centrifuge/tables/{f}", f=COMPARE_TABLES),
        *expand("results/centrifuge/figures/{f}", f=COMPARE_FIGURES.values()),
        *expand(
            "results/centrifuge/{f}",
            f=design_targets(MC_HOOKS["centrifuge"].cases(CEN), CEN_DESIGN),
        ),
        "results/centrifuge/report.md",
    ]
)

# what the centrifuge's claims are judged on (platcal.rigs.centrifuge.claims): its report opens on them
CENTRIFUGE_EVIDENCE = (
    []
    if CEN is None
    else [
        "results/centrifuge/montecarlo/coef.parquet",
        "results/centrifuge/montecarlo/runs.parquet",
        "results/centrifuge/compare/coef.parquet",
        "results/centrifuge/compare/runs.parquet",
    ]
)


wildcard_constraints:
    design=r"ga_[A-Za-z0-9_]+",


rule centrifuge_single_run:
    input:
        rig_requires("centrifuge"),
    output:
        estimates="results/centrifuge/single/estimates.csv",
        covariance="results/centrifuge/single/covariance.csv",
        history="results/centrifuge/single/history.parquet",
        info="results/centrifuge/single/run.json",
        timing="results/centrifuge/single/timing.json",
    params:
        single=lambda w: single_params(CEN),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 1
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_single_run"),
    log:
        "results/centrifuge/logs/single_run.log",
    script:
        "../scripts/centrifuge_single_run.py"


rule centrifuge_tables:
    input:
        coef="results/centrifuge/montecarlo/coef.parquet",
        runs="results/centrifuge/montecarlo/runs.parquet",
        timing="results/centrifuge/montecarlo/timing.csv",
        single=rules.centrifuge_single_run.output,
    output:
        csv=expand("results/centrifuge/tables/{table}.csv", table=TABLES),
        md=expand("results/centrifuge/tables/{table}.md", table=TABLES),
        table2_single=report(
            "results/centrifuge/tables/table2_single.html",
            caption="../report/table2_single.rst",
            category="Rig 1: centrifuge",
            subcategory="tables",
        ),
        table2_montecarlo=report(
            "results/centrifuge/tables/table2_montecarlo.html",
            caption="../report/table2_montecarlo.rst",
            category="Rig 1: centrifuge",
            subcategory="tables",
        ),
        summary=report(
            "results/centrifuge/tables/summary.html",
            caption="../report/summary.rst",
            category="Rig 1: centrifuge",
            subcategory="tables",
        ),
        timing="results/centrifuge/tables/summary_timing.csv",
    params:
        study=config_provider("centrifuge", "study", "noise", "seed"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_tables"),
    log:
        "results/centrifuge/logs/tables.log",
    script:
        "../scripts/centrifuge_tables.py"


rule centrifuge_figures:
    input:
        coef="results/centrifuge/montecarlo/coef.parquet",
        runs="results/centrifuge/montecarlo/runs.parquet",
        t2mc="results/centrifuge/tables/table2_montecarlo.csv",
        single=rules.centrifuge_single_run.output,
    output:
        boxplot=report(
            "results/centrifuge/figures/rel_err_boxplot.png",
            caption="../report/boxplot.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        rms_vs_noise=report(
            "results/centrifuge/figures/rms_vs_noise.png",
            caption="../report/rms_vs_noise.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        convergence=report(
            "results/centrifuge/figures/convergence.png",
            caption="../report/convergence.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        correlation=report(
            "results/centrifuge/figures/correlation.png",
            caption="../report/correlation.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        nees=report(
            "results/centrifuge/figures/nees_hist.png",
            caption="../report/nees.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        paper_vs_mc=report(
            "results/centrifuge/figures/paper_vs_montecarlo.png",
            caption="../report/paper_vs_mc.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
    params:
        study=config_provider("centrifuge", "study", "noise"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_figures"),
    log:
        "results/centrifuge/logs/figures.log",
    script:
        "../scripts/centrifuge_figures.py"


# ---- the estimator comparison (issue 9): its own cells, study.compare

CEN_COMPARE = [] if CEN is None else compare_cells(CEN)
# one job per noise level runs every estimator of the level (issue 22 item 4: one process start-up
# per level instead of one per estimator)
CEN_COMPARE_DIRS = [f"results/centrifuge/compare/noise{n}" for n in dict.fromkeys(n for n, _ in CEN_COMPARE)]
# the comparison's own module (its cells' job, settings and params) is outside the rig's compute
# closure, which follows the Monte Carlo hooks' imports (the hooks name it by path): its edit
# reruns the comparison's cells too
CODE_COMPARE = code_hash(["platcal.rigs.centrifuge.compare_cells"])


rule centrifuge_compare_cell:
    input:
        rig_requires("centrifuge"),
    output:
        coef="results/centrifuge/compare/noise{noise}/coef.parquet",
        runs="results/centrifuge/compare/noise{noise}/runs.parquet",
        timing="results/centrifuge/compare/noise{noise}/timing.json",
    params:
        # every estimator's cell params: an edit of one estimator's settings reruns its level
        cells=lambda w: compare_level_params(CEN, compare_levels(CEN)[w.noise]),
        level=lambda w: compare_levels(CEN)[w.noise],
        code=lambda w: CODE_COMPUTE["centrifuge"],
        compare_code=CODE_COMPARE,
    threads: 1
    # before the sweep's cells: 50-60 s each (a level's estimators) against their 4-10 s, so the
    # short cells end the run
    priority: 1
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_compare_cell", "noise{noise}"),
    log:
        "results/centrifuge/logs/compare/noise{noise}.log",
    script:
        "../scripts/centrifuge_compare_cell.py"


rule centrifuge_compare_collect:
    input:
        coef=[f"{d}/coef.parquet" for d in CEN_COMPARE_DIRS],
        runs=[f"{d}/runs.parquet" for d in CEN_COMPARE_DIRS],
        timing=[f"{d}/timing.json" for d in CEN_COMPARE_DIRS],
    output:
        coef="results/centrifuge/compare/coef.parquet",
        runs="results/centrifuge/compare/runs.parquet",
        timing="results/centrifuge/compare/timing.csv",
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_compare_collect"),
    log:
        "results/centrifuge/logs/compare/collect.log",
    script:
        "../scripts/centrifuge_compare_collect.py"


rule centrifuge_compare:
    input:
        coef="results/centrifuge/compare/coef.parquet",
        runs="results/centrifuge/compare/runs.parquet",
    output:
        tables=expand("results/centrifuge/tables/{f}", f=COMPARE_TABLES),
        cost=report(
            "results/centrifuge/figures/compare_cost.png",
            caption="../report/compare_cost.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
        nees=report(
            "results/centrifuge/figures/compare_nees.png",
            caption="../report/compare_nees.rst",
            category="Rig 1: centrifuge",
            subcategory="figures",
        ),
    params:
        study=config_provider("centrifuge", "study", "noise", "filter", "seed"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_compare"),
    log:
        "results/centrifuge/logs/compare/tables.log",
    script:
        "../scripts/centrifuge_compare.py"


rule centrifuge_report:
    input:
        tables=rules.centrifuge_tables.output,
        figures=rules.centrifuge_figures.output,
        compare=rules.centrifuge_compare.output.tables,
        timing="results/centrifuge/montecarlo/timing.csv",
        claims="results/centrifuge/claims.csv",
    output:
        "results/centrifuge/report.md",
    params:
        study=config_provider("centrifuge", "study", "noise", "seed"),
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_report"),
    log:
        "results/centrifuge/logs/report_md.log",
    script:
        "../scripts/centrifuge_report.py"


# ---- scheme design (issue 4): GA schemes, criteria against Monte Carlo, N, 1 g, D_OO


rule centrifuge_design_all:
    input:
        "results/centrifuge/design/report.md",


rule centrifuge_design_scheme:
    input:
        # the GA runs the centrifuge's EKF kernel: started before the kernels job had compiled it,
        # it compiled the kernel a second time beside it (50 s of its 101 s in one study run)
        rig_requires("centrifuge"),
    output:
        scheme="results/centrifuge/design/{design}.yaml",
        history="results/centrifuge/design/{design}.history.csv",
        population="results/centrifuge/design/{design}.population.csv",
        summary="results/centrifuge/design/{design}.json",
    params:
        model=config_provider("centrifuge", *DESIGN_KEYS),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    # one thread, started first: the GA scheme's Monte Carlo cells and the report wait for it, and
    # a two-thread job on two cores waits for both to be free at once (it had run last, alone);
    # one thread also runs the cells' serial EKF kernel, so nothing is compiled twice (issue 22)
    threads: 1
    priority: 10
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_scheme", "{design}"),
    log:
        "results/centrifuge/logs/design/{design}.log",
    script:
        "../scripts/centrifuge_design_scheme.py"


rule centrifuge_design_compare:
    input:
        schemes=expand("results/centrifuge/design/{d}.yaml", d=GA_CRITERIA),
    output:
        summary="results/centrifuge/design/compare/schemes.csv",
        spearman="results/centrifuge/design/compare/spearman.csv",
        figure=report(
            "results/centrifuge/design/compare/criteria_vs_accuracy.png",
            category="Rig 1: centrifuge",
            subcategory="design",
            caption="../report/design_scatter.rst",
        ),
    params:
        model=config_provider("centrifuge", *DESIGN_KEYS),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_compare"),
    log:
        "results/centrifuge/logs/design/compare.log",
    script:
        "../scripts/centrifuge_design_compare.py"


rule centrifuge_design_npos:
    input:
        schemes=expand("results/centrifuge/design/{d}.yaml", d=GA_NPOS),
    output:
        table="results/centrifuge/design/npos/n_positions.csv",
        figure=report(
            "results/centrifuge/design/npos/n_positions.png",
            category="Rig 1: centrifuge",
            subcategory="design",
            caption="../report/design_npos.rst",
        ),
    params:
        model=config_provider("centrifuge", *DESIGN_KEYS),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_npos"),
    log:
        "results/centrifuge/logs/design/npos.log",
    script:
        "../scripts/centrifuge_design_npos.py"


rule centrifuge_design_static:
    input:
        schemes=expand("results/centrifuge/design/{d}.yaml", d=GA_CRITERIA[:1]),
    output:
        table="results/centrifuge/design/static/static_vs_centrifuge.csv",
        summary="results/centrifuge/design/static/static_vs_centrifuge_summary.csv",
    params:
        model=config_provider("centrifuge", *DESIGN_KEYS),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 1
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_static"),
    log:
        "results/centrifuge/logs/design/static.log",
    script:
        "../scripts/centrifuge_design_static.py"


rule centrifuge_design_doo:
    input:
        scheme="results/centrifuge/design/ga_doo.yaml",
    output:
        covariance="results/centrifuge/design/doo/doo_covariance.csv",
        aliasing="results/centrifuge/design/doo/doo_aliasing.csv",
    params:
        model=config_provider("centrifuge", *DESIGN_KEYS),
        code=lambda w: CODE_COMPUTE["centrifuge"],
    threads: 2
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_doo"),
    log:
        "results/centrifuge/logs/design/doo.log",
    script:
        "../scripts/centrifuge_design_doo.py"


rule centrifuge_design_report:
    input:
        compare="results/centrifuge/design/compare/schemes.csv",
        npos="results/centrifuge/design/npos/n_positions.csv",
        static="results/centrifuge/design/static/static_vs_centrifuge.csv",
        doo="results/centrifuge/design/doo/doo_covariance.csv",
        schemes=expand("results/centrifuge/design/{d}.yaml", d=GA_CRITERIA),
    output:
        report(
            "results/centrifuge/design/report.md",
            category="Rig 1: centrifuge",
            subcategory="design",
            caption="../report/design_report.rst",
        ),
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("centrifuge", "centrifuge_design_report"),
    log:
        "results/centrifuge/logs/design/report.log",
    script:
        "../scripts/centrifuge_design_report.py"
