# The claims ledger (every paper claim computed from the study, platcal.study.claims) and
# results/report.md, the index of the study: it opens on the ledger of every rig, then one
# section per rig linking its report, then the calibration campaign's report when one is planned
# (workflow/rules/campaign.smk, included before this file), then "Where the time goes": every
# job's benchmark file (results/benchmarks/, written by the rules' benchmark: directives) summed
# per rig and rule, also results/timing.{csv,md,html}. report_index runs last (its inputs close
# over every rig's targets), so the files it sums are this study's.


INDEX_REPORT = "results/report.md"
LEDGER = expand("results/claims.{ext}", ext=["csv", "md", "html"])


rule claims:
    input:
        claims_evidence,
    output:
        expand("results/{{ledger_rig}}/claims.{ext}", ext=["csv", "md", "html"]),
    wildcard_constraints:
        ledger_rig="|".join(RIGS) or "(?!)",
    params:
        config=lambda w: MC_CONFIG.get(w.ledger_rig, RAW.get(w.ledger_rig)),  # checked where the rig checks
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("{ledger_rig}", "claims"),
    log:
        "results/{ledger_rig}/logs/claims.log",
    script:
        "../scripts/claims.py"


rule ledger:
    input:
        expand("results/{rig}/claims.csv", rig=RIGS),
    output:
        LEDGER[0],
        LEDGER[1],
        report(LEDGER[2], caption="../report/ledger.rst", category="0. Claims ledger (all rigs)"),
        "results/claims_front.html",  # the compact ledger the HTML report's front page embeds
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("study", "ledger"),
    log:
        "results/logs/ledger.log",
    script:
        "../scripts/ledger.py"


rule report_index:
    input:
        reports=[f"results/{r}/report.md" for r in RIGS],
        ledger=LEDGER[0],
        campaign=[t for t in CAMPAIGN_TARGETS if t.endswith("report.md")],
    output:
        report(INDEX_REPORT, caption="../report/index.rst", category="0. Claims ledger (all rigs)"),
        timing=["results/timing.csv", "results/timing.md"],
        timing_html=report(
            "results/timing.html", caption="../report/timing.rst", category="Where the time goes (all rigs)"
        ),
    params:
        rigs=RIGS,
        benchmarks=BENCH_ROOT,
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("study", "report_index"),
    log:
        "results/logs/report_index.log",
    script:
        "../scripts/report_index.py"


rule generic_report:
    """The report of a rig without rules of its own, from its Monte Carlo tidy tables."""
    input:
        coef="results/{generic_rig}/montecarlo/coef.parquet",
        runs="results/{generic_rig}/montecarlo/runs.parquet",
    output:
        "results/{generic_rig}/report.md",
        expand("results/{{generic_rig}}/tables/summary.{ext}", ext=["csv", "md", "html"]),
        "results/{generic_rig}/figures/nees.png",
    wildcard_constraints:
        generic_rig="|".join(r for r in RIGS if not RIG_RULES[r]) or "(?!)",
    params:
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("{generic_rig}", "generic_report"),
    log:
        "results/{generic_rig}/logs/generic_report.log",
    script:
        "../scripts/generic_report.py"
