"""Rig 2: the 1 g multi-position self-test with gimbal angle sensors (docs/multiposition-1g.md, seed 002).

A three-gimbal platform (middle gimbal limited to |beta| <= beta_max) turned by its own gimbals
to K positions at 1 g; a 27-state EKF on the three accelerometers and the three gimbal angle
sensors; a Lie-derivative rank test and a covariance check that accept or refuse a scheme.
"""

from ...lighttable import Table
from ...rig import Rig
from .config import load_config
from .estimators import ESTIMATORS
from .filter import position_information
from .model import coef_names, group_of, truth_vector, unit_of
from .montecarlo import MultipositionMonteCarlo


def catalogue():
    """The 24 identified coefficients (§15 names, state order), units, groups and default truth:
    a pandas DataFrame for the study's tables (:meth:`platcal.lighttable.Table.to_pandas`, so
    registering the rig loads no pandas)."""
    names = coef_names()
    return Table({"name": names, "group": [group_of(n) for n in names],
                  "unit": [unit_of(n) for n in names], "truth": truth_vector()}).to_pandas()


# the command line's and the campaign's modules by path (imported when first read, platcal.rig.LAZY_FIELDS):
# a Monte Carlo cell registers the rig and imports neither (issue 22 item 4)
RIG = Rig(name="multiposition", title="1 g multi-position self-test, 27-state EKF with gimbal angle sensors",
          spec="multiposition-1g.md", load_config=load_config, commands=f"{__name__}.commands:COMMANDS", catalogue=catalogue,
          estimators=tuple(ESTIMATORS), extras={"information": position_information, "claims": f"{__name__}.claims"},
          montecarlo=MultipositionMonteCarlo(), options=f"{__name__}.commands:OPTIONS", sizes=f"{__name__}.commands:sizes",
          campaign=f"{__name__}.campaign:CAMPAIGN")
