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
from .campaign import CAMPAIGN
from .catalogue import load_catalogue
from .commands import COMMANDS, OPTIONS, sizes
from .config import study_from_config
from .estimators import kind_names
from .study import CentrifugeMonteCarlo

RIG = Rig(name="centrifuge", title="precision centrifuge, 48-state EKF", spec="centrifuge-model.md",
          load_config=study_from_config, commands=COMMANDS, catalogue=lambda: load_catalogue().frame(),
          extras={"claims": f"{__name__}.claims"}, estimators=kind_names(), montecarlo=CentrifugeMonteCarlo(), options=OPTIONS,
          campaign=CAMPAIGN, sizes=sizes)
