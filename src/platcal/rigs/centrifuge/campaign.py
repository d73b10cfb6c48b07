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
from .identify import simulate_identify
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

    @staticmethod
    def full_truth(study, truth: Mapping[str, float]) -> np.ndarray:
        """The 48-vector of the study's truth with the campaign's platform values put in."""
        full = np.array(study.truth, float)
        for i, n in enumerate(FULL_NAMES):
            if n in truth:
                full[i] = float(truth[n])
        return full

    def information(self, study, scheme: str, dwell_s: float, truth: Mapping[str, float]) -> TestInformation:
        """Information of ``scheme`` at ``dwell_s`` s per position about the estimated coefficients
        (engineering units: the EKF's normalised information scaled by its P0 sigmas)."""
        whole_periods(dwell_s, study.filter.period_s, "dwell_s", "filter periods")
        setup = setup_from_study(replace(study, truth=self.full_truth(study, truth)), dwell_s)
        sch = self.scheme(study, scheme)
        F = position_information(setup, sch.angles_deg, None if sch.g_levels is None else np.asarray(sch.g_levels))
        p0 = setup.p0
        names = tuple(FULL_NAMES[i] for i in study.filter.coef_index)
        return TestInformation(names=names, information=F.sum(axis=0) / np.outer(p0, p0), prior_sigma=p0,
                               seconds=float(dwell_s) * sch.n_positions)


    def identify(self, study, scheme: str, dwell_s: float, truth: Mapping[str, float], prior_x: np.ndarray,
                 prior_P: np.ndarray, seeds) -> tuple[np.ndarray, np.ndarray]:
        """Simulate the test once per seed and identify it with the paper's EKF (one pass: a
        further pass restarts from 100 x its covariance and would drop the prior) started from
        ``prior_x`` (B, nc) and ``prior_P`` (B, nc, nc); returns the coefficients' estimate and
        covariance (engineering units, the names of :meth:`information`)."""
        whole_periods(dwell_s, study.filter.period_s, "dwell_s", "filter periods")
        sch = replace(self.scheme(study, scheme), dwell_s=float(dwell_s))
        fs = replace(study.filter, history_every_s=None, estimator="ekf", passes=1, estimator_options=(),
                     prior_x=np.asarray(prior_x, float), prior_P=np.asarray(prior_P, float))
        est = simulate_identify(study, sch, list(seeds), settings=fs, truth=self.full_truth(study, truth))
        nc = fs.coef_index.size
        return est.x[:, :nc], est.P[:, :nc, :nc]


CAMPAIGN = CentrifugeCampaign()
