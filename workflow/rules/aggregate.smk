# Study-wide tidy tables, then Table 2 (one run and Monte Carlo) and the summary.


rule collect:
    input:
        coef=expand("{cell}/coef.parquet", cell=CELLS),
        runs=expand("{cell}/runs.parquet", cell=CELLS),
        timing=expand("{cell}/timing.json", cell=CELLS),
    output:
        coef="results/montecarlo/coef.parquet",
        runs="results/montecarlo/runs.parquet",
        timing="results/montecarlo/timing.csv",
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/collect.log",
    script:
        "../scripts/collect.py"


rule tables:
    input:
        coef=rules.collect.output.coef,
        runs=rules.collect.output.runs,
        timing=rules.collect.output.timing,
        single=rules.single_run.output,
    output:
        csv=expand("results/tables/{table}.csv", table=TABLES),
        md=expand("results/tables/{table}.md", table=TABLES),
        table2_single=report(
            "results/tables/table2_single.html",
            caption="../report/table2_single.rst",
            category="Tables",
        ),
        table2_montecarlo=report(
            "results/tables/table2_montecarlo.html",
            caption="../report/table2_montecarlo.rst",
            category="Tables",
        ),
        summary=report(
            "results/tables/summary.html",
            caption="../report/summary.rst",
            category="Tables",
        ),
        timing="results/tables/summary_timing.csv",
    params:
        study=STUDY,
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/tables.log",
    script:
        "../scripts/tables.py"
