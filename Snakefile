# platcal: Monte Carlo studies of platform-error identification on each test rig.
#   snakemake --cores 2                        the default study (config/config.yaml: one entry per rig)
#   snakemake --cores 2 --configfile FILE      another study (e.g. config/test.yaml, merged over it)
#   snakemake --report results/report.html     the HTML report, after a run
# The science lives in the installed package `platcal`; rules and scripts are thin wrappers.
# Each rig's rules file reads its config from config["rigs"][<rig>] and defines <RIG>_TARGETS
# (empty when the rig is not in the index); the generic Monte Carlo rules serve every rig with
# Monte Carlo hooks (platcal.rig).
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/montecarlo.smk"
include: "workflow/rules/centrifuge.smk"
include: "workflow/rules/multiposition.smk"
include: "workflow/rules/sled.smk"
include: "workflow/rules/lowprec_centrifuge.smk"
include: "workflow/rules/report.smk"


RIG_TARGETS = {
    "centrifuge": CENTRIFUGE_TARGETS,
    "multiposition": MULTIPOSITION_TARGETS,
    "sled": SLED_TARGETS,
    "lowprec_centrifuge": LOWPREC_CENTRIFUGE_TARGETS,
}


rule all:
    default_target: True
    input:
        CENTRIFUGE_TARGETS,
        MULTIPOSITION_TARGETS,
        SLED_TARGETS,
        LOWPREC_CENTRIFUGE_TARGETS,
        LEDGER,
        INDEX_REPORT,
