# Rig 3, the rocket-sled one-dimensional motion constraint (docs/rocket-sled.md; issue 11).
# Reads its config from config["rigs"]["sled"]; defines SLED_TARGETS (results/sled/..., ending
# with results/sled/report.md), or an empty list when the key is absent.
# One job per study case (6- vs 7-state, realtime vs post, misalignment 0, paper tuning), one
# for the rank table, one for the summary (Table-1 analogue, checks, figures, report.md).

from platcal.rigs.sled.config import load_config as _sled_load_config
from platcal.rigs.sled.study import case_config as _sled_case_config
from platcal.study.montecarlo import package_code_hash as _sled_code_hash

SLED_TARGETS = []
if "sled" in RAW:
    SLED_RAW = RAW["sled"]  # the one config path (common.smk): a file or an inline mapping
    _SLED_STUDY = checked("sled", _sled_load_config).study
    for _sled_case in _SLED_STUDY["cases"]:  # every case's config (base + overrides) before any job
        checked("sled", lambda raw: _sled_case_config(raw, _sled_case))
    SLED_CASES = list(_SLED_STUDY["cases"])
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

    rule sled_case:
        output:
            metrics="results/sled/cases/{case}/metrics.csv",
            series="results/sled/cases/{case}/series.csv",
        params:
            raw={k: v for k, v in SLED_RAW.items() if k != "study"},  # a case reads no study key but seeds
            seeds=_SLED_STUDY["seeds"],
            code=SLED_CODE,
        wildcard_constraints:
            case="|".join(SLED_CASES),
        threads: 1
        conda:
            "../envs/platcal.yaml"
        log:
            "results/logs/sled/case_{case}.log",
        script:
            "../scripts/sled_case.py"

    rule sled_observability:
        output:
            "results/sled/rank_table.csv",
            "results/sled/rank_table.md",
            "results/sled/rank_table.html",
        params:
            raw={k: SLED_RAW[k] for k in ("rig", "site", "trajectory") if k in SLED_RAW},  # what the ranks read
            code=SLED_CODE,
        conda:
            "../envs/platcal.yaml"
        log:
            "results/logs/sled/observability.log",
        script:
            "../scripts/sled_observability.py"

    rule sled_summary:
        input:
            metrics=expand("results/sled/cases/{case}/metrics.csv", case=SLED_CASES),
            series=expand("results/sled/cases/{case}/series.csv", case=SLED_CASES),
            ranks="results/sled/rank_table.csv",
        output:
            "results/sled/table1.md",
            "results/sled/checks.md",
            report("results/sled/figures/yz_before_after.png", category="Rig 3: sled"),
            report("results/sled/figures/x_error.png", category="Rig 3: sled"),
            report("results/sled/figures/attitude.png", category="Rig 3: sled"),
            report="results/sled/report.md",
        params:
            raw=SLED_RAW,
            cases=SLED_CASES,
            code=SLED_CODE,
        conda:
            "../envs/platcal.yaml"
        log:
            "results/logs/sled/summary.log",
        script:
            "../scripts/sled_summary.py"
