"""The multiposition rig's estimators by name (issue 9 item 5; docs/multiposition-1g.md §9, §16).

``filter.estimator`` in the config names one entry of :data:`ESTIMATORS`; ``filter.passes``
applies to every sequential estimator (later passes restart from the previous estimate with
P0 = 100 x its coefficient covariance, §9); each estimator's own options sit under
``filter.<name>`` (``filter.iekf: {iterations, tolerance}``).

- ``ekf``: the EKF of §9 (the patent's filter), :func:`.filter.run_filter` with
  ``iterations = 0``.
- ``iekf``: the Gauss-Newton iterated EKF (:mod:`platcal.estimation.iterated`): each 6-D update
  relinearised at most ``iterations`` times, stopping when the step is below ``tolerance``
  prior sigmas; Joseph-form covariance; the propagation as the EKF's.

Adding an estimator (e.g. a UKF built on :mod:`platcal.estimation.unscented`): write a function
with the signature of :func:`run_ekf_estimator` returning an :class:`Estimate`, add it to
:data:`ESTIMATORS`, and its options (if any) as ``filter.<name>`` in
``data/config.schema.yaml``; the config check, ``platcal identify --estimator`` and the study's
``study.estimators`` variants then accept it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from .filter import run_filter, run_filter_positions


@dataclass(frozen=True)
class Estimate:
    """Output of an estimator on R replicates: coefficients (R, nc), covariance (R, nc, nc),
    mean NIS per measurement component (R,), measurement linearisations per update (R,), updates
    skipped because the innovation covariance was not positive definite (R,)."""

    coef: np.ndarray
    cov: np.ndarray
    mean_nis: np.ndarray
    linearisations: np.ndarray
    failed_updates: np.ndarray


def _estimates(on_pass):
    """``on_pass(p, Estimate)`` as :func:`.filter.run_filter`'s ``on_pass`` (None stays None)."""
    return None if on_pass is None else (lambda p, result, _innovations: on_pass(p, Estimate(*result)))


def run_ekf_estimator(cfg, positions_deg, t, Z, nk=None, passes=None, options=None, threads=None,
                      sigma_a_ug=None, innovations=None, on_pass=None) -> Estimate:
    """The EKF of §9 (``innovations``: see :func:`.filter.run_filter`)."""
    return Estimate(*run_filter(cfg, positions_deg, t, Z, nk, passes, threads=threads, sigma_a_ug=sigma_a_ug,
                                innovations=innovations, on_pass=_estimates(on_pass)))


def run_iekf_estimator(cfg, positions_deg, t, Z, nk=None, passes=None, options=None, threads=None,
                       sigma_a_ug=None, innovations=None, on_pass=None) -> Estimate:
    """The Gauss-Newton iterated EKF; ``options`` = ``filter.iekf`` (iterations, tolerance)."""
    iterations, tolerance = linearisations(FilterChoice("iekf", 1, options or {}))
    return Estimate(*run_filter(cfg, positions_deg, t, Z, nk, passes, threads=threads, sigma_a_ug=sigma_a_ug,
                                iterations=iterations, tolerance=tolerance, innovations=innovations,
                                on_pass=_estimates(on_pass)))


Runner = Callable[..., Estimate]
ESTIMATORS: dict[str, Runner] = {"ekf": run_ekf_estimator, "iekf": run_iekf_estimator}
"""Estimator name -> runner ``(cfg, positions_deg, t, Z, nk, passes, options, threads, sigma_a_ug,
innovations, on_pass)``; ``on_pass(p, Estimate)``, when given, after each pass but the last with
the estimate of a run of p passes (:func:`.filter.run_filter`; every estimator here is
sequential, so every one hands its passes)."""

ESTIMATOR_DEFAULTS: dict[str, dict] = {"ekf": {}, "iekf": {"iterations": 3, "tolerance": 0.01}}
"""Default options per estimator (the schema's defaults of ``filter.<name>``)."""


@dataclass(frozen=True)
class FilterChoice:
    """An estimator with its passes and options, e.g. ``iekf``, 1 pass, ``{iterations: 3, ...}``."""

    estimator: str
    passes: int
    options: dict

    @property
    def label(self) -> str:
        return f"{self.estimator} ({self.passes} pass{'es' if self.passes > 1 else ''})"


def check_estimator(name, field: str) -> str:
    """``name`` if it is a registered estimator; InputError naming ``field`` otherwise."""
    if name not in ESTIMATORS:
        raise InputError(field, f"unknown estimator {name!r}; rig multiposition has {sorted(ESTIMATORS)}")
    return name


def choice_from_filter(filter_section: dict) -> FilterChoice:
    """The :class:`FilterChoice` of a (validated) ``filter`` section."""
    est = filter_section["estimator"]
    return FilterChoice(est, int(filter_section["passes"]),
                        {**ESTIMATOR_DEFAULTS.get(est, {}), **dict(filter_section.get(est) or {})})


def variant_choice(cfg, name: str, field: str = "--estimator") -> FilterChoice:
    """A study variant (a key of ``study.estimators``: overrides of ``filter``) or a registered
    estimator name (the config's ``filter`` with ``estimator`` replaced)."""
    return raw_variant_choice(cfg.raw, name, field)


def raw_variant_choice(raw: dict, name: str, field: str = "--estimator") -> FilterChoice:
    """:func:`variant_choice` of a validated config mapping."""
    variants = raw["study"]["estimators"]
    f = dict(raw["filter"])
    if name in variants:
        v = dict(variants[name])
        for k, val in v.items():
            f[k] = {**(f.get(k) or {}), **val} if isinstance(val, dict) else val
    elif name in ESTIMATORS:
        f["estimator"] = name
    else:
        raise InputError(field, f"unknown estimator {name!r}; use one of {sorted(ESTIMATORS)} or a key of "
                         f"study.estimators {sorted(variants)}")
    return choice_from_filter(f)


def estimate(cfg, choice: FilterChoice, positions_deg, t, Z, nk=None, threads=None, sigma_a_ug=None,
             innovations=None, on_pass=None) -> Estimate:
    """Run the estimator of ``choice`` on outputs ``Z`` (R, K, n, 6); ``innovations`` (R, K, n, 12),
    when given, receives the last pass's innovations and S diagonals (:func:`.filter.run_filter`);
    ``on_pass(p, Estimate)`` as in :data:`ESTIMATORS`."""
    return ESTIMATORS[choice.estimator](cfg, positions_deg, t, Z, nk=nk, passes=choice.passes,
                                        options=choice.options, threads=threads, sigma_a_ug=sigma_a_ug,
                                        innovations=innovations, on_pass=on_pass)


def linearisations(choice: FilterChoice) -> tuple[int, float]:
    """``(iterations, tolerance)`` of :func:`.filter.run_filter` for ``choice`` (docs/multiposition-1g.md
    §9): 0 for the EKF, the ``filter.iekf`` options (defaults :data:`ESTIMATOR_DEFAULTS`) for the
    iterated EKF; ValueError for an estimator that is neither (it has its own runner)."""
    if choice.estimator == "ekf":
        return 0, 0.0
    if choice.estimator != "iekf":
        raise ValueError(f"estimator {choice.estimator!r} is not run by run_filter's linearisations")
    o = {**ESTIMATOR_DEFAULTS["iekf"], **(choice.options or {})}
    return int(o["iterations"]), float(o["tolerance"])


def estimate_positions(cfg, choice: FilterChoice, positions_deg, source, on_innovations=None) -> Estimate:
    """:func:`estimate` (docs/multiposition-1g.md §9) of one record fed one position at a time (a streamed record,
    :func:`.filter.run_filter_positions`: ``source()`` yields each position's ``(t, z)`` per pass);
    the estimators of :data:`ESTIMATORS` are all sequential, so every one streams."""
    iterations, tolerance = linearisations(choice)
    return Estimate(*run_filter_positions(cfg, positions_deg, source, choice.passes, iterations, tolerance,
                                          on_innovations))
