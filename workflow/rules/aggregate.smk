# Study-wide tidy tables, then Table 2 (one run and Monte Carlo) and the summary.


rule collect:
    input:
        coef=expand("{cell}/coef.parquet", cell=CELLS),
        runs=expand("{cell}/runs.parquet", cell=CELLS),
        timing=expand("{cell}/timing.json", cell=CELLS),
    output:
        coef=RESULTS + "/montecarlo/coef.parquet",
        runs=RESULTS + "/montecarlo/runs.parquet",
        timing=RESULTS + "/montecarlo/timing.csv",
    params:
        code=CODE_ALL,
    log:
        RESULTS + "/logs/collect.log",
    script:
        "../scripts/collect.py"


rule tables:
    input:
        coef=rules.collect.output.coef,
        runs=rules.collect.output.runs,
        timing=rules.collect.output.timing,
        single=rules.single_run.output,
    output:
        csv=expand(RESULTS + "/tables/{table}.csv", table=TABLES),
        md=expand(RESULTS + "/tables/{table}.md", table=TABLES),
        table2_single=report(
            RESULTS + "/tables/table2_single.html",
            caption="../report/table2_single.rst",
            category="Tables",
        ),
        table2_montecarlo=report(
            RESULTS + "/tables/table2_montecarlo.html",
            caption="../report/table2_montecarlo.rst",
            category="Tables",
        ),
        summary=report(
            RESULTS + "/tables/summary.html",
            caption="../report/summary.rst",
            category="Tables",
        ),
        timing=RESULTS + "/tables/summary_timing.csv",
    params:
        study=STUDY,
        code=CODE_ALL,
    log:
        RESULTS + "/logs/tables.log",
    script:
        "../scripts/tables.py"
