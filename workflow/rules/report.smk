# results/report.md: tables inline, figures linked, a short reading of the numbers.


rule report_md:
    input:
        tables=rules.tables.output,
        figures=rules.figures.output,
        timing=rules.collect.output.timing,
    output:
        REPORT_MD,
    params:
        study=STUDY,
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/report_md.log",
    script:
        "../scripts/report_md.py"
