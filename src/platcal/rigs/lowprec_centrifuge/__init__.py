"""Rig 4, low-precision centrifuge: accelerometer asymmetry and second-order coefficients of a
platform INS by a variable-period Kalman filter, against the traditional two-level method
(``docs/lowprec-centrifuge.md``, seed 004).

Modules: ``config`` (schema, :class:`Study`), ``profile`` (run profiles, kinematics), ``truth``
(residual draws, the simulated runs, 5 lock-step variants), ``insim`` (the independent truth: the
platform INS navigated through the table's motion), ``errormodel`` (the §5 error model along a
specific force: a log's compensation), ``record`` (the test record),
``proposed`` (windows, observations, 14-state filter), ``traditional`` (eq. 2), ``metrics``
(compensation, effect), ``scenario`` (the §2 scenarios, failed fits, traces; no pandas), ``study`` (tables
from the tidy Monte Carlo tables), ``montecarlo`` (the
hooks of the generic Monte Carlo runner), ``report`` (tables, figures, report),
``commands`` (the CLI).
"""

import numpy as np

from ...lighttable import Table
from ...rig import Rig
from .config import COEFFS, load_config
from .montecarlo import UNITS, LowprecMonteCarlo


def catalogue():
    """The identified coefficients; truth is per platform (config ``platforms``), hence NaN here. A
    pandas DataFrame (:meth:`platcal.lighttable.Table.to_pandas`: registering the rig loads no pandas)."""
    return Table({"name": list(COEFFS), "group": ["accel"] * 4,
                  "unit": [UNITS[c[:2]] for c in COEFFS], "truth": [np.nan] * 4}).to_pandas()


COMMANDS = {**{name: f"{__name__}.commands:{name}" for name in ("inspect", "simulate", "identify", "compensate")},
            "kernels": f"{__name__}.aot_kernels:kernels_command"}
"""The sub-commands by module path (:func:`platcal.rig.resolve`): a Monte Carlo cell registers the
rig and does not import the command line's module (issue 22 item 4); ``kernels`` builds the
identify's kernels ahead of time (:mod:`.aot_kernels`)."""

RIG = Rig(name="lowprec_centrifuge",
          title="low-precision centrifuge: accelerometer nonlinearity by a variable-period Kalman filter",
          spec="lowprec-centrifuge.md", load_config=load_config, commands=COMMANDS,
          catalogue=catalogue, extras={"claims": f"{__name__}.claims"}, estimators=("proposed", "traditional"),
          options=f"{__name__}.commands:OPTIONS", montecarlo=LowprecMonteCarlo(), sizes=f"{__name__}.commands:sizes")
