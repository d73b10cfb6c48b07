# Rig 4, low-precision centrifuge (docs/lowprec-centrifuge.md): the default scenario and the
# centrifuge-imprecision sweep of section 2, one job per scenario, then tables, figures, report.
# Reads its config from config["rigs"]["lowprec_centrifuge"]; without that key it defines no target.
import re as _lp_re

LOWPREC_CENTRIFUGE_TARGETS = []
if config.get("rigs", {}).get("lowprec_centrifuge"):
    from platcal.errors import InputError as _LpInputError
    from platcal.cli import read_config as _lp_read_config
    from platcal.rigs.lowprec_centrifuge.config import load_config as _lp_load
    from platcal.rigs.lowprec_centrifuge.study import scenarios as _lp_scenarios
    from platcal.study.montecarlo import package_code_hash as _lp_code_hash
    from snakemake.exceptions import WorkflowError as _LpWorkflowError

    LOWPREC_CFG = config["rigs"]["lowprec_centrifuge"]
    try:
        _LP_STUDY = _lp_load(_lp_read_config(LOWPREC_CFG))   # UTF-8 YAML, else InputError
    except _LpInputError as exc:
        raise _LpWorkflowError(f"invalid configuration {LOWPREC_CFG}: {exc.field}: {exc.message}")
    LOWPREC_SCENARIOS = list(_lp_scenarios(_LP_STUDY))
    LOWPREC_CODE = _lp_code_hash("platcal.rigs.lowprec_centrifuge")  # a code edit reruns the jobs
    LOWPREC_FILES = expand(
        "results/lowprec_centrifuge/tables/{t}.{ext}",
        t=["table1", "table1_y", "coefficients", "degradation", "acceptance", "cross_validation"],
        ext=["csv", "md", "html"],
    ) + expand(
        "results/lowprec_centrifuge/figures/{f}.png",
        f=["effect_vs_imprecision", "velocity_trace", "windows_heading"],
    )
    LOWPREC_CENTRIFUGE_TARGETS = LOWPREC_FILES + ["results/lowprec_centrifuge/report.md"]

    rule lowprec_scenario:
        output:
            cross="results/lowprec_centrifuge/scenarios/{scen}/cross.csv",
            coeffs="results/lowprec_centrifuge/scenarios/{scen}/coeffs.csv",
            trace="results/lowprec_centrifuge/scenarios/{scen}/trace.npz",
        wildcard_constraints:
            scen="|".join(_lp_re.escape(s) for s in LOWPREC_SCENARIOS),
        params:
            config=LOWPREC_CFG,
            code=LOWPREC_CODE,
        threads: 1
        conda:
            "../envs/platcal.yaml"
        log:
            "results/lowprec_centrifuge/logs/scenario_{scen}.log",
        script:
            "../scripts/lowprec_scenario.py"

    rule lowprec_report:
        input:
            cross=expand("results/lowprec_centrifuge/scenarios/{scen}/cross.csv", scen=LOWPREC_SCENARIOS),
            coeffs=expand("results/lowprec_centrifuge/scenarios/{scen}/coeffs.csv", scen=LOWPREC_SCENARIOS),
            trace="results/lowprec_centrifuge/scenarios/default/trace.npz",
        output:
            report="results/lowprec_centrifuge/report.md",
            files=[
                report(f, category="Rig 4: lowprec_centrifuge") if f.endswith(".png") else f
                for f in LOWPREC_FILES
            ],
        params:
            config=LOWPREC_CFG,
            names=LOWPREC_SCENARIOS,
            code=LOWPREC_CODE,
        conda:
            "../envs/platcal.yaml"
        log:
            "results/lowprec_centrifuge/logs/report.log",
        script:
            "../scripts/lowprec_report.py"
