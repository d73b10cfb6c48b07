# Rig 2, the 1 g multi-position self-test (docs/multiposition-1g.md): scheme check of every named
# scheme, GA design, the section 13 comparison with the centrifuge's Table 1; tables, figures and
# report under results/multiposition/. Its Monte Carlo (schemes x sigma_a x estimators x seeds) is
# the generic stage of workflow/rules/montecarlo.smk (rules montecarlo_cell and collect; hooks
# platcal.rigs.multiposition.montecarlo.MultipositionMonteCarlo), whose tidy tables the report reads.
# The rig's config is RAW["multiposition"] (common.smk; the centrifuge's RAW["centrifuge"]);
# without it MULTIPOSITION_TARGETS is empty. Set-up: platcal.rigs.multiposition.study.WorkflowSetup.
from platcal.rigs.multiposition.study import WorkflowSetup as _MPSetup

# the rig config (path or inline, RAW of common.smk) is validated, field named, before any job runs
MP_SETUP = (checked("multiposition", lambda raw: _MPSetup(raw, centrifuge="centrifuge" in RAW))
            if "multiposition" in RAW else _MPSetup(None))
MULTIPOSITION_TARGETS = MP_SETUP.targets()
# what the rig's claims are judged on (platcal.rigs.multiposition.claims): its report opens on them
MULTIPOSITION_EVIDENCE = (
    [
        *MP_SETUP.observability(),
        "results/multiposition/montecarlo/coef.parquet",
        "results/multiposition/montecarlo/runs.parquet",
        "results/multiposition/extension/ranks.json",
        "results/multiposition/extension/spread.csv",
    ]
    if MULTIPOSITION_TARGETS
    else []
)


rule multiposition_lie_cache:
    output:
        "results/multiposition/lie_cache.json",
    params:
        config=MP_SETUP.rule_config("lie_cache"),
        code=MP_SETUP.code,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_lie_cache"),
    log:
        "results/multiposition/logs/lie_cache.log",
    script:
        "../scripts/multiposition_lie_cache.py"


rule multiposition_observability:
    input:
        "results/multiposition/lie_cache.json",
        "results/multiposition/kernels.json",
    output:
        MP_SETUP.observability(),
    params:
        config=MP_SETUP.rule_config("observability"),
        code=MP_SETUP.code,
        schemes=MP_SETUP.study["rank_schemes"],
        outdirs=[f"results/multiposition/observability/{s}" for s in MP_SETUP.study["rank_schemes"]],
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_observability"),
    log:
        "results/multiposition/logs/observability.log",
    script:
        "../scripts/multiposition_observability.py"


rule multiposition_design:
    input:
        "results/multiposition/kernels.json",
    output:
        expand("results/multiposition/design/GA{k}.yaml", k=MP_SETUP.design_k),
        ga="results/multiposition/design/GA.yaml",
        compare="results/multiposition/design/compare.csv",
    priority: 10  # the GA scheme's Monte Carlo cells wait for it: start it first
    params:
        config=MP_SETUP.rule_config("design"),
        code=MP_SETUP.code,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_design"),
    log:
        "results/multiposition/logs/design.log",
    script:
        "../scripts/multiposition_design.py"


rule multiposition_extension:
    input:
        "results/multiposition/lie_cache.json",
        "results/multiposition/kernels.json",
    output:
        ranks="results/multiposition/extension/ranks.json",
        sigma="results/multiposition/extension/sigma.csv",
        spread="results/multiposition/extension/spread.csv",
    params:
        config=MP_SETUP.rule_config("extension"),
        code=MP_SETUP.code,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_extension"),
    log:
        "results/multiposition/logs/extension.log",
    script:
        "../scripts/multiposition_extension.py"


rule multiposition_centrifuge_table1:
    input:
        # its information runs are the centrifuge's covariance-only EKF: beside the kernels job
        # (no input, it could start first) it would compile that kernel a second time (issue 22)
        rig_requires("centrifuge"),
    output:
        "results/multiposition/centrifuge_table1/observability.json",
    params:
        config=lambda w: {k: v for k, v in RAW["centrifuge"].items() if k != "study"},
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_centrifuge_table1"),
    log:
        "results/multiposition/logs/centrifuge_table1.log",
    script:
        "../scripts/observability_of_config.py"


rule multiposition_report:
    input:
        obs=MP_SETUP.observability(),
        coef="results/multiposition/montecarlo/coef.parquet",
        runs="results/multiposition/montecarlo/runs.parquet",
        timing="results/multiposition/montecarlo/timing.csv",
        design="results/multiposition/design/compare.csv",
        ext_ranks="results/multiposition/extension/ranks.json",
        ext_sigma="results/multiposition/extension/sigma.csv",
        ext_spread="results/multiposition/extension/spread.csv",
        centrifuge=MP_SETUP.centrifuge_json(),
        claims="results/multiposition/claims.csv",
    output:
        tables=expand(
            "results/multiposition/tables/{table}.{ext}",
            table=["ranks", "montecarlo_summary", "design", "extension_ranks", "extension_sigma"],
            ext=["csv", "md", "html"],
        ),
        figures=[
            report(f, category="Rig 2: multiposition", subcategory="figures")
            for f in expand(
                "results/multiposition/figures/{fig}.png",
                fig=["ranks", "montecarlo", "nees", "extension", "extension_draws"],
            )
        ],
        report="results/multiposition/report.md",
    params:
        config=MP_SETUP.config,
        code=MP_SETUP.code,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("multiposition", "multiposition_report"),
    log:
        "results/multiposition/logs/report.log",
    script:
        "../scripts/multiposition_report.py"
