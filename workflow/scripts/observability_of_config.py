"""`platcal observability` of a rule's config content (no config path: the content is the param)."""
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import yaml

from platcal.cli import main
from platcal.parallel import set_threads

sm = snakemake  # noqa: F821
# the rule's threads, not numba's default of every core: one thread runs the serial EKF kernel
# the centrifuge's Monte Carlo cells also compile, and no thread waits for a busy core
set_threads(sm.threads)
with tempfile.TemporaryDirectory() as d, open(sm.log[0], "w") as log, redirect_stdout(log), redirect_stderr(log):
    cfg = Path(d) / "config.yaml"
    cfg.write_text(yaml.safe_dump(dict(sm.params.config)), encoding="utf-8")
    status = main(["observability", "--config", str(cfg), "--scheme", "table1", "--out", str(Path(sm.output[0]).parent)])
sys.exit(status)
