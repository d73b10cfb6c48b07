"""The precision centrifuge, 48-state EKF (``docs/centrifuge-model.md``, seed 000).

Its code still lives in the top-level modules; the CLI runs it through their commands until it
moves here (issue 8).
"""

from ...config import load_config as _load  # noqa: F401  (kept for the registry's shape)
from ...instruments import load_catalogue
from ...rig import Rig

RIG = Rig(name="centrifuge", title="precision centrifuge, 48-state EKF", spec="centrifuge-model.md",
          load_config=lambda raw: raw, commands={}, catalogue=lambda: load_catalogue().frame(),
          estimators=("ekf",))
