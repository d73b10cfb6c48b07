# Every figure from the collected results and the single run (PNG, byte-stable).


rule figures:
    input:
        coef=rules.collect.output.coef,
        runs=rules.collect.output.runs,
        t2mc=RESULTS + "/tables/table2_montecarlo.csv",
        single=rules.single_run.output,
    output:
        boxplot=report(
            RESULTS + "/figures/" + FIGURES["boxplot"],
            caption="../report/boxplot.rst",
            category="Figures",
        ),
        rms_vs_noise=report(
            RESULTS + "/figures/" + FIGURES["rms_vs_noise"],
            caption="../report/rms_vs_noise.rst",
            category="Figures",
        ),
        convergence=report(
            RESULTS + "/figures/" + FIGURES["convergence"],
            caption="../report/convergence.rst",
            category="Figures",
        ),
        correlation=report(
            RESULTS + "/figures/" + FIGURES["correlation"],
            caption="../report/correlation.rst",
            category="Figures",
        ),
        nees=report(
            RESULTS + "/figures/" + FIGURES["nees"],
            caption="../report/nees.rst",
            category="Figures",
        ),
        paper_vs_mc=report(
            RESULTS + "/figures/" + FIGURES["paper_vs_mc"],
            caption="../report/paper_vs_mc.rst",
            category="Figures",
        ),
    params:
        study=STUDY,
        code=CODE_ALL,
    log:
        RESULTS + "/logs/figures.log",
    script:
        "../scripts/figures.py"
