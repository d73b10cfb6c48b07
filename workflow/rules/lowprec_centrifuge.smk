# Rig 4, low-precision centrifuge (docs/lowprec-centrifuge.md): the default scenario and the
# centrifuge-imprecision sweep of section 2, one job per scenario, then tables, figures, report.
# Reads its config (path or inline) from config["rigs"]["lowprec_centrifuge"] through RAW
# (common.smk); without that key it defines no target. Each scenario job's param is the
# scenario's own config (study.scenario_config): an edit reruns exactly the scenarios it changes.
import re as _lp_re

LOWPREC_CENTRIFUGE_TARGETS = []
if "lowprec_centrifuge" in RAW:
    from platcal.rigs.lowprec_centrifuge.config import load_config as _lp_load
    from platcal.rigs.lowprec_centrifuge.study import scenario_config as _lp_scenario_config
    from platcal.rigs.lowprec_centrifuge.study import scenarios as _lp_scenarios
    from platcal.study.montecarlo import package_code_hash as _lp_code_hash

    _LP_STUDY = checked("lowprec_centrifuge", _lp_load)
    LOWPREC_SCENARIOS = list(_lp_scenarios(_LP_STUDY))
    LOWPREC_SCENARIO_CONFIG = {s: _lp_scenario_config(_LP_STUDY, s) for s in LOWPREC_SCENARIOS}
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
            config=lambda w: LOWPREC_SCENARIO_CONFIG[w.scen],
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
            config=_LP_STUDY.raw,
            names=LOWPREC_SCENARIOS,
            code=LOWPREC_CODE,
        conda:
            "../envs/platcal.yaml"
        log:
            "results/lowprec_centrifuge/logs/report.log",
        script:
            "../scripts/lowprec_report.py"
