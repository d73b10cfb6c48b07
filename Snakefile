# platcal: Monte Carlo studies of platform-error identification on each test rig.
#   snakemake --cores 2                        the default study (config/config.yaml: one entry per rig)
#   snakemake --cores 2 --configfile FILE      another study (e.g. config/test.yaml, merged over it)
#   snakemake --report results/report.html     the HTML report, after a run
# The science lives in the installed package `platcal`; rules and scripts are thin wrappers.
# Rigs are found, not listed (platcal.rig.rig_modules): each rig of the index gets the generic
# Monte Carlo rules when it has Monte Carlo hooks, its own rules file when it has one
# (workflow/rules/<rig>.smk or Rig.rules, defining <RIG>_TARGETS), else the generic report.
import os

from snakemake.utils import min_version

from platcal.study import forkserver

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/montecarlo.smk"


for _rules in dict.fromkeys(f for f in RIG_RULES.values() if f):
    include: _rules


include: "workflow/rules/campaign.smk"
include: "workflow/rules/report.smk"


RIG_TARGETS = {
    r: globals()[f"{r.upper()}_TARGETS"] if RIG_RULES[r] else [f"results/{r}/report.md"] for r in RIGS
}


rule all:
    default_target: True
    input:
        [t for r in RIGS for t in RIG_TARGETS[r]],
        LEDGER if RIGS else [],
        INDEX_REPORT if RIGS else [],
        CAMPAIGN_TARGETS,


# One process imports what the jobs import, and forks each job's process (platcal.study.forkserver):
# about 0.3-1.5 s CPU of imports less per job. Jobs that start before it is ready, or that it
# refuses (more than one thread, another interpreter), run in their own interpreters as before.
FORKSERVER = []


onstart:
    FORKSERVER.append(
        forkserver.start(
            ".snakemake/platcal",
            os.path.join(workflow.basedir, "workflow", "scripts"),
            RIGS,
            {r.name: str(r.benchmark) for r in workflow.rules if r.benchmark},
        )
    )


onsuccess:
    forkserver.stop(FORKSERVER.pop() if FORKSERVER else None)


onerror:
    forkserver.stop(FORKSERVER.pop() if FORKSERVER else None)
