# Rig 3, the rocket-sled one-dimensional motion constraint (docs/rocket-sled.md; issue 11).
# Its config is config["rigs"]["sled"] (a path or an inline mapping), checked once in common.smk
# (MC_CONFIG["sled"]); defines SLED_TARGETS (results/sled/..., ending with results/sled/report.md),
# or an empty list when the rig is not in the index.
# The cases' replicates run as generic Monte Carlo cells (montecarlo.smk; hooks in
# platcal.rigs.sled.montecarlo) collected into results/sled/montecarlo/{coef,runs}.parquet; they and
# the series wait for the rig's kernels job (the generic rule kernels). Here: the rank table, each
# case's replicate 0 as time series for the figures, and the summary (Table-1 analogue, checks,
# figures, report.md). Each rule's params are the config it reads.

from platcal.rigs.sled.montecarlo import case_params as _sled_case_params
from platcal.study.montecarlo import package_code_hash as _sled_code_hash

SLED_TARGETS = []
if "sled" in MC_CONFIG:
    SLED_CASES = MC_HOOKS["sled"].cases(MC_CONFIG["sled"])
    SLED_CODE = _sled_code_hash("platcal.rigs.sled")
    SLED_TARGETS = [
        "results/sled/table1.md",
        "results/sled/checks.md",
        "results/sled/rank_table.md",
        "results/sled/figures/yz_before_after.png",
        "results/sled/figures/x_error.png",
        "results/sled/figures/attitude.png",
        "results/sled/report.md",
    ]
    # what the rig's claims are judged on (platcal.rigs.sled.claims): its report opens on them
    SLED_EVIDENCE = ["results/sled/montecarlo/runs.parquet"]

    rule sled_series:
        input:
            rig_requires("sled"),
        output:
            "results/sled/series/{case}.csv",
        params:
            case=lambda w: _sled_case_params(MC_CONFIG["sled"], w.case),
            code=SLED_CODE,
        wildcard_constraints:
            case="|".join(SLED_CASES),
        conda:
            "../envs/platcal.yaml"
        benchmark:
            bench("sled", "sled_series", "series_{case}"),
        log:
            "results/sled/logs/series_{case}.log",
        script:
            "../scripts/sled_series.py"

    rule sled_observability:
        output:
            "results/sled/rank_table.csv",
            "results/sled/rank_table.md",
            "results/sled/rank_table.html",
        params:
            # the rank table reads the site, the trajectory, the IMU rate and the filter period
            cfg=config_provider("sled", "rig", "site", "trajectory", "imu", "filter"),
            code=SLED_CODE,
        conda:
            "../envs/platcal.yaml"
        benchmark:
            bench("sled", "sled_observability"),
        log:
            "results/sled/logs/observability.log",
        script:
            "../scripts/sled_observability.py"

    rule sled_summary:
        input:
            runs="results/sled/montecarlo/runs.parquet",
            series=expand("results/sled/series/{case}.csv", case=SLED_CASES),
            ranks="results/sled/rank_table.csv",
            claims="results/sled/claims.csv",
        output:
            "results/sled/table1.md",
            "results/sled/checks.md",
            report("results/sled/figures/yz_before_after.png", category="Rig 3: sled", subcategory="figures"),
            report("results/sled/figures/x_error.png", category="Rig 3: sled", subcategory="figures"),
            report("results/sled/figures/attitude.png", category="Rig 3: sled", subcategory="figures"),
            report="results/sled/report.md",
        params:
            # the report prints the whole config
            cfg=lambda w: MC_CONFIG["sled"],
            code=SLED_CODE,
        conda:
            "../envs/platcal.yaml"
        benchmark:
            bench("sled", "sled_summary"),
        log:
            "results/sled/logs/summary.log",
        script:
            "../scripts/sled_summary.py"
