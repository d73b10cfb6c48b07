# The generic Monte Carlo stage of every rig with Monte Carlo hooks (platcal.rig.MonteCarloHooks):
# one job per (case, noise level) cell running every estimator on the cell's data, then the rig's
# tidy tables; before them, for a rig whose hooks have ``warm_kernels``, one job compiling its
# numba kernels (rule kernels).
#   results/<rig>/runs/<case>/noise<level>/{coef,runs}.parquet, timing.json
#   results/<rig>/montecarlo/{coef,runs}.parquet, timing.csv



wildcard_constraints:
    rig="|".join(MC_CONFIG) or "(?!)",
    scheme=r"[A-Za-z0-9_.-]+",
    noise=r"[0-9][0-9.e+-]*",


rule kernels:
    output:
        "results/{rig}/kernels.json",
    wildcard_constraints:
        rig="|".join(WARM_RIGS) or "(?!)",
    priority: 20  # every job running the rig's estimators waits for it (rig_requires)
    params:
        # compiling depends on the code only: a config change reruns no cell through this file
        code=lambda w: CODE_COMPUTE[w.rig],
    threads: 1
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("{rig}", "kernels"),
    log:
        "results/{rig}/logs/kernels.log",
    script:
        "../scripts/kernels.py"


rule montecarlo_cell:
    input:
        case=mc_case_input,
        requires=mc_requires_input,
    output:
        # one folder per estimator: coef.parquet, runs.parquet, timing.json (the rig's own per-run
        # columns differ between estimators: they stay each in its own tables, as collect reads them)
        directory("results/{rig}/runs/{scheme}/noise{noise}"),
    params:
        cell=mc_cell_params,  # estimator -> what its numbers depend on
        level=lambda w: MC_LEVELS[w.rig][w.noise],
        code=lambda w: CODE_COMPUTE[w.rig],
    threads: mc_threads
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("{rig}", "montecarlo_cell", "{scheme}_noise{noise}"),
    log:
        "results/{rig}/logs/montecarlo/{scheme}_noise{noise}.log",
    script:
        "../scripts/montecarlo_cell.py"


rule collect:
    input:
        cells=lambda w: mc_cells(w.rig),
    output:
        coef="results/{rig}/montecarlo/coef.parquet",
        runs="results/{rig}/montecarlo/runs.parquet",
        timing="results/{rig}/montecarlo/timing.csv",
    params:
        estimators=mc_estimators,
        code=CODE_ALL,
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("{rig}", "collect"),
    log:
        "results/{rig}/logs/collect.log",
    script:
        "../scripts/collect.py"
