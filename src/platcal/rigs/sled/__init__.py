"""Rig 3: the rocket-sled one-dimensional motion constraint (``docs/rocket-sled.md``, seed 003).

An IMU on a rocket sled moves along the track only, so the lateral and vertical navigation
errors measure its attitude error; a 6- (or 7-) state run filter and a ZUPT stop filter
estimate it and the along-track (X) error is compensated open loop. Modules: :mod:`.config`
(schema, §10), :mod:`.trajectory` (§2), :mod:`.sensors` (§3), :mod:`.ins` (§4),
:mod:`.errmodel` (§5), :mod:`.filters` (§6), :mod:`.identify` (§7-8), :mod:`.observability`
(§8), :mod:`.record` (§10), :mod:`.commands` (CLI), :mod:`.montecarlo` (the Monte Carlo hooks,
§12), :mod:`.study` (the study's tables, figures and report).
"""

import numpy as np

from ...lighttable import Table
from ...rig import Rig
from .config import load_config
from .montecarlo import SledMonteCarlo


def catalogue():
    """The identified quantities (no default truth: it is drawn per seed), a pandas DataFrame
    (:meth:`platcal.lighttable.Table.to_pandas`: registering the rig loads no pandas)."""
    rows = [("phi_x", "attitude", "arcsec"), ("phi_y", "attitude", "arcsec"), ("phi_z", "attitude", "arcsec"),
            ("nabla_x", "accel", "ug")]
    return Table({"name": [r[0] for r in rows], "group": [r[1] for r in rows], "unit": [r[2] for r in rows],
                  "truth": np.full(len(rows), np.nan)}).to_pandas()


# the command line's module by path (imported when first read, platcal.rig.LAZY_FIELDS): a Monte
# Carlo cell registers the rig and does not import it (issue 22 item 4)
RIG = Rig(name="sled", title="rocket-sled one-dimensional motion constraint, 6/7-state run + ZUPT filters",
          spec="rocket-sled.md", load_config=load_config, commands=f"{__name__}.commands:COMMANDS", catalogue=catalogue,
          extras={"claims": f"{__name__}.claims"}, estimators=("run6", "run7"), montecarlo=SledMonteCarlo(),
          options=f"{__name__}.commands:OPTIONS", sizes=f"{__name__}.commands:sizes")
