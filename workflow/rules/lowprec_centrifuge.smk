# Rig 4, low-precision centrifuge (docs/lowprec-centrifuge.md): the default scenario and the
# centrifuge-imprecision sweep of section 2 (scenarios x proposed/traditional x seeds) are the
# generic stage of workflow/rules/montecarlo.smk (rules montecarlo_cell and collect; hooks
# platcal.rigs.lowprec_centrifuge.montecarlo.LowprecMonteCarlo); here the figures' traces and the
# tables, figures and report from the tidy tables. Each rule's params hold the config content its
# outputs depend on (config_provider, common.smk); without config["rigs"]["lowprec_centrifuge"]
# LOWPREC_CENTRIFUGE_TARGETS is empty.
from platcal.study.montecarlo import package_code_hash as _lp_code_hash

LOWPREC_CENTRIFUGE_TARGETS = []
if "lowprec_centrifuge" in MC_CONFIG:
    LOWPREC_CODE = _lp_code_hash("platcal.rigs.lowprec_centrifuge")  # a code edit reruns the rules
    LOWPREC_FILES = expand(
        "results/lowprec_centrifuge/tables/{t}.{ext}",
        t=["table1", "table1_y", "coefficients", "degradation", "acceptance", "cross_validation"],
        ext=["csv", "md", "html"],
    ) + expand(
        "results/lowprec_centrifuge/figures/{f}.png",
        f=["effect_vs_imprecision", "velocity_trace", "windows_heading"],
    )
    LOWPREC_CENTRIFUGE_TARGETS = LOWPREC_FILES + ["results/lowprec_centrifuge/report.md"]

    rule lowprec_trace:
        output:
            "results/lowprec_centrifuge/trace.npz",
        params:
            cfg=config_provider("lowprec_centrifuge", "rig", "seed", "site", "centrifuge", "platforms", "runs",
                                "profile", "traditional", "residuals"),
            code=LOWPREC_CODE,
        conda:
            "../envs/platcal.yaml"
        benchmark:
            bench("lowprec_centrifuge", "lowprec_trace"),
        log:
            "results/lowprec_centrifuge/logs/trace.log",
        script:
            "../scripts/lowprec_trace.py"

    rule lowprec_report:
        input:
            coef="results/lowprec_centrifuge/montecarlo/coef.parquet",
            runs="results/lowprec_centrifuge/montecarlo/runs.parquet",
            trace="results/lowprec_centrifuge/trace.npz",
        output:
            report="results/lowprec_centrifuge/report.md",
            files=[
                report(f, category="Rig 4: lowprec_centrifuge") if f.endswith(".png") else f
                for f in LOWPREC_FILES
            ],
        params:
            cfg=config_provider("lowprec_centrifuge", "rig", "seed", "site", "centrifuge", "platforms", "runs",
                                "profile", "traditional", "residuals", "study"),
            code=LOWPREC_CODE,
        conda:
            "../envs/platcal.yaml"
        benchmark:
            bench("lowprec_centrifuge", "lowprec_report"),
        log:
            "results/lowprec_centrifuge/logs/report.log",
        script:
            "../scripts/lowprec_report.py"
