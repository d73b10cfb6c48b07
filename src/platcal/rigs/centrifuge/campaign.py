"""The centrifuge's campaign hooks: the Fisher information of one test for ``platcal plan``.

A test is a scheme of the config (or ``classical``) at a dwell per position. Its information is
the sum of the per-position informations of the covariance-only EKF (docs/centrifuge-model.md
§10: the attitude reset at each position makes them independent and additive;
:func:`.observability.position_information`), linearised about the campaign's platform truth.
The 45 coefficients carry the platform's names; DOO_x/y/z (when estimated) are nuisance states.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ...errors import InputError
from ...model.instruments import FULL_NAMES
from ...rig import TestInformation
from ...scheme import whole_periods
from .observability import position_information, setup_from_study
from .study import builtin_scheme


class CentrifugeCampaign:
    """Campaign hooks of the precision centrifuge (see :class:`platcal.rig.CampaignHooks`)."""

    def schemes(self, study) -> list[str]:
        return sorted(study.config["schemes"]) + ["classical"]

    def scheme(self, study, name: str):
        if name not in self.schemes(study):
            raise InputError("scheme", f"unknown centrifuge scheme {name!r}; use one of {self.schemes(study)}")
        return builtin_scheme(study.config, name)

    def positions(self, study, scheme: str) -> int:
        return self.scheme(study, scheme).n_positions

    def information(self, study, scheme: str, dwell_s: float, truth: Mapping[str, float]) -> TestInformation:
        """Information of ``scheme`` at ``dwell_s`` s per position about the estimated coefficients
        (engineering units: the EKF's normalised information scaled by its P0 sigmas)."""
        whole_periods(dwell_s, study.filter.period_s, "dwell_s", "filter periods")
        full = np.array(study.truth, float)
        for i, n in enumerate(FULL_NAMES):
            if n in truth:
                full[i] = float(truth[n])
        setup = setup_from_study(replace(study, truth=full), dwell_s)
        sch = self.scheme(study, scheme)
        F = position_information(setup, sch.angles_deg, None if sch.g_levels is None else np.asarray(sch.g_levels))
        p0 = setup.p0
        names = tuple(FULL_NAMES[i] for i in study.filter.coef_index)
        return TestInformation(names=names, information=F.sum(axis=0) / np.outer(p0, p0), prior_sigma=p0,
                               seconds=float(dwell_s) * sch.n_positions)


CAMPAIGN = CentrifugeCampaign()
