"""The multiposition rig's campaign hooks: the Fisher information of one 1 g self-test.

A test is a scheme of the config at a dwell per position; its information is the sum of the
per-position informations of the covariance-only EKF (docs/multiposition-1g.md §8, §14; the
attitude reset at each position makes them additive: :func:`.filter.position_information`),
linearised about the campaign's platform truth. Of the 24 coefficients, those the platform model
names (gyro DF, DI, DS, DO; accelerometer k0, k1, theta_py, theta_pz, theta_oz) map onto it;
the other misalignments (theta_px, theta_ox, theta_oy) are nuisance states.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ...errors import InputError
from ...parallel import get_threads
from ...rig import TestInformation
from .config import make_scheme
from .filter import position_information, run_filter, simulate
from .model import coef_names


class MultipositionCampaign:
    """Campaign hooks of the 1 g multi-position self-test (see :class:`platcal.rig.CampaignHooks`)."""

    def schemes(self, cfg) -> list[str]:
        return sorted(cfg.schemes)

    def scheme(self, cfg, name: str):
        if name not in cfg.schemes:
            raise InputError("scheme", f"unknown multiposition scheme {name!r}; use one of {self.schemes(cfg)}")
        return cfg.schemes[name]

    def positions(self, cfg, scheme: str) -> int:
        return self.scheme(cfg, scheme).n_positions

    @staticmethod
    def with_truth(cfg, truth: Mapping[str, float]):
        """The config with the campaign's platform values as its truth."""
        return replace(cfg, truth_overrides={**cfg.truth_overrides,
                                             **{n: float(truth[n]) for n in coef_names() if n in truth}})

    def information(self, cfg, scheme: str, dwell_s: float, truth: Mapping[str, float]) -> TestInformation:
        """Information of ``scheme`` at ``dwell_s`` s per position about the 24 coefficients
        (engineering units: the normalised information scaled by the rig's P0 sigmas)."""
        names = coef_names()
        cfg = self.with_truth(cfg, truth)
        F = position_information(cfg, self.scheme(cfg, scheme).angles_deg, float(dwell_s))
        p0 = cfg.p0()
        sch = self.scheme(cfg, scheme)
        return TestInformation(names=names, information=F.sum(axis=0) / np.outer(p0, p0), prior_sigma=p0,
                               seconds=float(dwell_s) * sch.n_positions)


    def identify(self, cfg, scheme: str, dwell_s: float, truth: Mapping[str, float], prior_x: np.ndarray,
                 prior_P: np.ndarray, seeds) -> tuple[np.ndarray, np.ndarray]:
        """Simulate the test once per seed and identify it with the EKF of §9 (one pass, so the
        handed-on prior is kept) started from ``prior_x`` (B, 24) and ``prior_P`` (B, 24, 24);
        returns the 24 coefficients' estimate and covariance (engineering units). At the
        caller's numba threads (:func:`platcal.parallel.get_threads`; the numbers do not depend on
        them): the filter's default, a thread per core, made a one-thread job wait on a thread
        pool for a core another job held."""
        cfg = self.with_truth(cfg, truth)
        base = self.scheme(cfg, scheme)
        sch = make_scheme(base.name, base.positions, float(dwell_s), cfg.beta_max_deg)
        n = get_threads()
        t, _, z = simulate(cfg, sch, list(seeds), threads=n)
        x, P = run_filter(cfg, sch.angles_deg, t, z, passes=1, prior_x=prior_x, prior_P=prior_P, threads=n)[:2]
        return x, P


CAMPAIGN = MultipositionCampaign()
