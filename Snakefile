# platcal: the Monte Carlo study of centrifuge identification (issue 3).
#   snakemake --cores 2                        the default study (config/config.yaml)
#   snakemake --cores 2 --configfile FILE      another study (e.g. config/test.yaml)
#   snakemake --report results/report.html     the HTML report, after a run
# The science lives in the installed package `platcal`; rules and scripts are thin wrappers.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/montecarlo.smk"
include: "workflow/rules/aggregate.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/report.smk"


# the genetic-algorithm design (results/design/<name>.yaml for ga_* schemes), once it lands;
# design.smk sets DESIGN_TARGETS (the design report) when design.study.report is true
DESIGN_TARGETS = []
if Path(workflow.basedir, "workflow/rules/design.smk").exists():

    include: "workflow/rules/design.smk"


rule all:
    default_target: True
    input:
        REPORT_MD,
        ALL_TABLES,
        ALL_FIGURES,
        DESIGN_TARGETS,
