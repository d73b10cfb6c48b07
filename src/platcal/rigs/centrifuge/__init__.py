"""The precision centrifuge: 45 platform error coefficients by a 48-state EKF
(``docs/centrifuge-model.md``, seed 000; Xu & Zhang 2017).

Modules: :mod:`.base` (the centrifuge's specific force), :mod:`.catalogue` (Table 2),
:mod:`.config` (schema and typed study), :mod:`.record`, :mod:`.simulate`,
:mod:`.ekf` (EKF and iterated EKF), :mod:`.estimators` (the registry of estimator kinds), :mod:`.identify` (the one simulate -> identify path), :mod:`.observability`
(covariance-only kernel), :mod:`.design` (GA), :mod:`.design_study`, :mod:`.study` (its Monte
Carlo hooks), :mod:`.tables` and :mod:`.report` (Table 2, figures, report section),
:mod:`.commands` (its ``platcal`` sub-commands).
"""

from ...rig import Rig
from .catalogue import load_catalogue
from .config import study_from_config
from .estimators import kind_names
from .study import CentrifugeMonteCarlo

# the command line's and the campaign's modules by path (imported when first read, platcal.rig.LAZY_FIELDS):
# a Monte Carlo cell registers the rig and imports neither (issue 22 item 4)
RIG = Rig(name="centrifuge", title="precision centrifuge, 48-state EKF", spec="centrifuge-model.md",
          load_config=study_from_config, commands=f"{__name__}.commands:COMMANDS", catalogue=lambda: load_catalogue().frame(),
          extras={"claims": f"{__name__}.claims"}, estimators=kind_names(), montecarlo=CentrifugeMonteCarlo(),
          options=f"{__name__}.commands:OPTIONS", campaign=f"{__name__}.campaign:CAMPAIGN", sizes=f"{__name__}.commands:sizes")
