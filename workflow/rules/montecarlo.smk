# One job per (scheme, noise level, estimator) cell: simulate + identify every replicate.


rule montecarlo_cell:
    input:
        scheme=scheme_input,
    output:
        coef=CELL_DIR + "/coef.parquet",
        runs=CELL_DIR + "/runs.parquet",
        timing=CELL_DIR + "/timing.json",
    params:
        cell=cell_params,
        code=CODE_COMPUTE,
    threads: STUDY["threads"]
    log:
        RESULTS + "/logs/montecarlo/{scheme}_sa{sigma}_{estimator}.log",
    script:
        "../scripts/montecarlo_cell.py"


rule single_run:
    output:
        estimates=RESULTS + "/single/estimates.csv",
        covariance=RESULTS + "/single/covariance.csv",
        history=RESULTS + "/single/history.parquet",
        info=RESULTS + "/single/run.json",
        timing=RESULTS + "/single/timing.json",
    params:
        single=single_params,
        code=CODE_COMPUTE,
    threads: 1
    log:
        RESULTS + "/logs/single_run.log",
    script:
        "../scripts/single_run.py"
