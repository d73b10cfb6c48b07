"""Snakemake wrapper: results/campaign/ (plan, coefficients, alternatives, check, figures, report)."""
from pathlib import Path

from platcal.log import job_logger
from platcal.parallel import set_threads
from platcal.study.campaign import run_campaign

sm = snakemake  # noqa: F821
# the rule's threads, not numba's default of every core: on a shared machine the extra thread
# waits for a core, and one thread runs the serial kernels the Monte Carlo cells also compile
set_threads(sm.threads)
log = job_logger(sm.log[0])
plan, checks = run_campaign(sm.params.campaign, Path(sm.output[0]).parent)
log.info("plan cost %.6g, meets every target: %s", plan.plan["cost"].sum(), plan.meets)
for name, c in checks.items():
    log.info("Monte Carlo of %s: %d replicates, mean NEES %.4g", name, c.replicates, c.nees.mean())
