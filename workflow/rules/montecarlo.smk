# One job per (scheme, noise level, estimator) cell: simulate + identify every replicate.


rule montecarlo_cell:
    input:
        scheme=scheme_input,
    output:
        coef="results/runs/{scheme}/sa{sigma}/{estimator}/coef.parquet",
        runs="results/runs/{scheme}/sa{sigma}/{estimator}/runs.parquet",
        timing="results/runs/{scheme}/sa{sigma}/{estimator}/timing.json",
    params:
        cell=cell_params,
        code=CODE_COMPUTE,
    threads: STUDY["threads"]
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/montecarlo/{scheme}_sa{sigma}_{estimator}.log",
    script:
        "../scripts/montecarlo_cell.py"


rule single_run:
    output:
        estimates="results/single/estimates.csv",
        covariance="results/single/covariance.csv",
        history="results/single/history.parquet",
        info="results/single/run.json",
        timing="results/single/timing.json",
    params:
        single=single_params,
        code=CODE_COMPUTE,
    threads: 1
    conda:
        "../envs/platcal.yaml"
    log:
        "results/logs/single_run.log",
    script:
        "../scripts/single_run.py"
