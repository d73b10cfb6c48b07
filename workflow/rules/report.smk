# results/report.md: the index of the study, one section per rig linking its report.


INDEX_REPORT = "results/report.md"


rule report_index:
    input:
        [f"results/{r}/report.md" for r in RIGS],
    output:
        report(INDEX_REPORT, caption="../report/index.rst", category="Study"),
    params:
        rigs=RIGS,
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/report_index.log",
    script:
        "../scripts/report_index.py"
