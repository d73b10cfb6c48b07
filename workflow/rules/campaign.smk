# The default calibration campaign (issue 23): `platcal plan` on the index's `campaign:` entry
# (config/campaign.yaml), written to results/campaign/. The rule's param is the campaign's content
# with each rig's config read in (platcal.study.campaign_file.campaign_content), never a path. Planned
# only when every rig the campaign names is in the study.
CAMPAIGN = campaign_param(config.get("campaign"), RIGS)
CAMPAIGN_TARGETS = (
    [f"results/campaign/{f}" for f in ("plan.csv", "coefficients.csv", "alternatives.csv", "report.md")]
    if CAMPAIGN
    else []
)


# What every Monte Carlo cell of a rig the campaign names waits for (rig_requires: the rig's
# kernels job, rule kernels or the multi-position rig's own). The plan's Monte Carlo check runs those rigs'
# filters: after that job they load from numba's cache, beside it they are compiled a second time
# (29 s of CPU on a cold cache; issue 22 item 4).
CAMPAIGN_REQUIRES = [f for r in ((CAMPAIGN or {}).get("rigs") or {}) for f in rig_requires(r)]


rule campaign_plan:
    input:
        CAMPAIGN_REQUIRES,
    output:
        report(
            "results/campaign/plan.csv", caption="../report/campaign.rst", category="Campaign (all rigs)"
        ),
        "results/campaign/coefficients.csv",
        "results/campaign/alternatives.csv",
        report(
            "results/campaign/front.png", caption="../report/campaign.rst", category="Campaign (all rigs)"
        ),
        report(
            "results/campaign/progress.png",
            caption="../report/campaign.rst",
            category="Campaign (all rigs)",
        ),
        report(
            "results/campaign/report.md", caption="../report/campaign.rst", category="Campaign (all rigs)"
        ),
    params:
        campaign=CAMPAIGN,
        code=CODE_ALL,
    threads: 1
    # the study's longest job after the kernels (about 50 s): started as soon as its rigs' kernels
    # are ready, so that short cells fill the cores at the end rather than it running last, alone
    priority: 5
    conda:
        "../envs/platcal.yaml"
    benchmark:
        bench("campaign", "campaign_plan"),
    log:
        "results/logs/campaign_plan.log",
    script:
        "../scripts/campaign_plan.py"
