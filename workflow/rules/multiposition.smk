# Rig 2, the 1 g multi-position self-test (docs/multiposition-1g.md): scheme check of every named
# scheme, GA design, Monte Carlo over seeds x schemes x noise x EKF passes, the section 13
# comparison with the centrifuge's Table 1; tables, figures and report under results/multiposition/.
# The rig's config path is config["rigs"]["multiposition"]; without it no target is defined.
import hashlib as _mp_hashlib
from pathlib import Path as _MPPath

from platcal.errors import InputError as _MPInputError
from platcal.io import read_yaml as _mp_read_yaml
from snakemake.exceptions import WorkflowError as _MPWorkflowError

MP = "results/multiposition"
MP_CONFIG = config.get("rigs", {}).get("multiposition")
MP_CENTRIFUGE = config.get("rigs", {}).get("centrifuge")
MULTIPOSITION_TARGETS = []


def _mp_code_hash():
    import platcal.rigs.multiposition as _pkg

    h = _mp_hashlib.sha256()
    root = _MPPath(_pkg.__file__).parent
    for p in sorted(root.rglob("*")):
        if p.suffix in (".py", ".yaml"):
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


if MP_CONFIG:
    from platcal.rigs.multiposition.config import load_config as _mp_load_config

    try:  # validated (field named) before any job runs
        _MP = _mp_load_config(_mp_read_yaml(_MPPath(MP_CONFIG).read_text()))
    except _MPInputError as exc:
        raise _MPWorkflowError(f"invalid {MP_CONFIG}: {exc.field}: {exc.message}")
    MP_STUDY = _MP.raw["study"]
    MP_DESIGN_K = list(_MP.raw["design"]["positions"])
    MP_SIGMAS = [f"{float(s):g}" for s in MP_STUDY["sigma_a_ug"]]
    MP_CODE = _mp_code_hash()
    MP_CELLS = expand(MP + "/runs/{scheme}/sa{sigma}.parquet", scheme=MP_STUDY["schemes"], sigma=MP_SIGMAS)
    MP_OBS = expand(MP + "/observability/{scheme}/observability.json", scheme=MP_STUDY["rank_schemes"])
    MP_CEN = [MP + "/centrifuge_table1/observability.json"] if MP_CENTRIFUGE else []
    MULTIPOSITION_TARGETS = [
        MP + "/tables/ranks.csv", MP + "/tables/montecarlo_summary.csv", MP + "/tables/design.csv",
        MP + "/tables/extension_sigma.csv", MP + "/figures/ranks.png", MP + "/figures/montecarlo.png",
        MP + "/figures/extension.png", MP + "/montecarlo/coef.parquet", MP + "/report.md",
    ]


def _mp_design_input(wildcards):
    """A GA scheme comes from the design rule; the config's schemes need no input."""
    if MP_CONFIG and wildcards.scheme not in _MP.schemes:
        return MP + f"/design/{wildcards.scheme}.yaml"
    return []


rule multiposition_lie_cache:
    output:
        MP + "/lie_cache.json",
    params:
        config=MP_CONFIG,
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/lie_cache.log",
    script:
        "../scripts/multiposition_lie_cache.py"


rule multiposition_observability:
    input:
        MP + "/lie_cache.json",
    output:
        MP + "/observability/{scheme}/observability.json",
    params:
        config=MP_CONFIG,
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/observability_{scheme}.log",
    shell:
        "platcal observability --config {params.config} --scheme {wildcards.scheme} "
        "--out {MP}/observability/{wildcards.scheme} > {log} 2>&1"


rule multiposition_design:
    output:
        expand(MP + "/design/GA{k}.yaml", k=MP_DESIGN_K if MP_CONFIG else []),
        ga=MP + "/design/GA.yaml",
        compare=MP + "/design/compare.csv",
    params:
        config=MP_CONFIG,
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/design.log",
    script:
        "../scripts/multiposition_design.py"


rule multiposition_montecarlo:
    input:
        _mp_design_input,
    output:
        MP + "/runs/{scheme}/sa{sigma}.parquet",
    wildcard_constraints:
        scheme=r"[A-Za-z0-9_.-]+",
        sigma=r"[0-9][0-9.e+-]*",
    params:
        config=MP_CONFIG,
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/montecarlo_{scheme}_sa{sigma}.log",
    script:
        "../scripts/multiposition_montecarlo.py"


rule multiposition_extension:
    input:
        MP + "/lie_cache.json",
    output:
        ranks=MP + "/extension/ranks.json",
        sigma=MP + "/extension/sigma.csv",
    params:
        config=MP_CONFIG,
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/extension.log",
    script:
        "../scripts/multiposition_extension.py"


rule multiposition_centrifuge_table1:
    output:
        MP + "/centrifuge_table1/observability.json",
    params:
        config=MP_CENTRIFUGE,
    log:
        MP + "/logs/centrifuge_table1.log",
    shell:
        "platcal observability --config {params.config} --scheme table1 --out {MP}/centrifuge_table1 > {log} 2>&1"


rule multiposition_report:
    input:
        obs=MP_OBS if MP_CONFIG else [],
        cells=MP_CELLS if MP_CONFIG else [],
        design=MP + "/design/compare.csv",
        ext_ranks=MP + "/extension/ranks.json",
        ext_sigma=MP + "/extension/sigma.csv",
        centrifuge=MP_CEN if MP_CONFIG else [],
    output:
        tables=[MP + f"/tables/{t}.{e}" for t in ("ranks", "montecarlo_summary", "design", "extension_ranks",
                                                  "extension_sigma") for e in ("csv", "md", "html")],
        figures=[MP + f"/figures/{f}.png" for f in ("ranks", "montecarlo", "extension")],
        coef=MP + "/montecarlo/coef.parquet",
        report=MP + "/report.md",
    params:
        code=MP_CODE if MP_CONFIG else "",
    log:
        MP + "/logs/report.log",
    script:
        "../scripts/multiposition_report.py"
