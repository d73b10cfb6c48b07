"""Rig 3: the rocket-sled one-dimensional motion constraint (``docs/rocket-sled.md``, seed 003).

An IMU on a rocket sled moves along the track only, so the lateral and vertical navigation
errors measure its attitude error; a 6- (or 7-) state run filter and a ZUPT stop filter
estimate it and the along-track (X) error is compensated open loop. Modules: :mod:`.config`
(schema, §10), :mod:`.trajectory` (§2), :mod:`.sensors` (§3), :mod:`.ins` (§4),
:mod:`.errmodel` (§5), :mod:`.filters` (§6), :mod:`.identify` (§7-8), :mod:`.observability`
(§8), :mod:`.record` (§10), :mod:`.commands` (CLI), :mod:`.montecarlo` (the Monte Carlo hooks,
§12), :mod:`.study` (the study's tables, figures and report).
"""

import pandas as pd

from ...rig import Rig
from .commands import COMMANDS, OPTIONS, sizes
from .config import load_config
from .montecarlo import SledMonteCarlo


def catalogue() -> pd.DataFrame:
    """The identified quantities (no default truth: it is drawn per seed)."""
    rows = [("phi_x", "attitude", "arcsec"), ("phi_y", "attitude", "arcsec"), ("phi_z", "attitude", "arcsec"),
            ("nabla_x", "accel", "ug")]
    return pd.DataFrame([{"name": n, "group": g, "unit": u, "truth": float("nan")} for n, g, u in rows])


RIG = Rig(name="sled", title="rocket-sled one-dimensional motion constraint, 6/7-state run + ZUPT filters",
          spec="rocket-sled.md", load_config=load_config, commands=COMMANDS, catalogue=catalogue,
          extras={"claims": f"{__name__}.claims"}, estimators=("run6", "run7"), montecarlo=SledMonteCarlo(), options=OPTIONS, sizes=sizes)
