"""The centrifuge's estimators by kind (issue 9 item 3): the registry behind ``filter.estimator``,
``study.estimators`` and ``platcal identify --estimator``.

Every kind provides one run function with the signature shared by the centrifuge's estimators
(notes: the contract of issue 9)::

    run(data: EstimatorInput, settings: FilterSettings, **options) -> Estimate

``data`` (:class:`platcal.rigs.centrifuge.ekf.EstimatorInput`): the outputs ``z`` (g) at the
instants ``t`` (s since each position's start; those of
:func:`platcal.rigs.centrifuge.ekf.filter_times`), the commanded angles and the centrifuge
parameters; batched over B replicates, bit-identical whatever B and the thread count.
``options`` are the kind's keywords; each maps from a key of the config's ``filter:`` section
(:attr:`EstimatorKind.config_keys`), so that a ``study.estimators`` entry, which overrides
``filter:`` keys, can set them.

Kinds
-----
- ``ekf``: the paper's EKF (docs/centrifuge-model.md §9), ``filter.passes`` passes; option
  ``filter.warmup_s`` (a warm-up pass over the first seconds of each position,
  :func:`platcal.rigs.centrifuge.ekf.run_ekf`).
- ``iekf``: the iterated EKF (Gauss-Newton relinearisation of each update,
  :func:`platcal.rigs.centrifuge.ekf.run_iekf`); options ``filter.iterations``,
  ``filter.iterate_tol``, ``filter.iterate_s``, ``filter.iterate_ratio``.
- ``ukf``: the unscented Kalman filter of the same model (sigma points over all states in the
  measurement update, the EKF's propagation, :func:`platcal.rigs.centrifuge.ukf.run_ukf`),
  ``filter.passes`` passes; options ``filter.ukf_sigma_points``, ``filter.ukf_alpha``,
  ``filter.ukf_beta``, ``filter.ukf_kappa``.
- ``ml``: the batch maximum-likelihood (MAP) estimate, Gauss-Newton over the whole record with
  the angle random walk whitened (:func:`platcal.rigs.centrifuge.ml.run_ml`); its covariance is
  the inverse information at the estimate (the Cramer-Rao bound of ``observability`` at the
  truth); ``passes`` does not apply; options ``filter.ml_max_iter``, ``filter.ml_tol``,
  ``filter.ml_start``, ``filter.ml_damping``, ``filter.ml_coarse``, ``filter.ml_final``.

The covariance-only runs of ``observability`` and ``design`` stay the EKF's
(:func:`platcal.rigs.centrifuge.ekf.run_ekf` with ``linearise_about``) whatever the kind.
Add a kind: its run function, an :class:`EstimatorKind` in :data:`KINDS`, its option keys in the
``filter`` section of ``data/config.schema.yaml`` (and in the ``study.estimators`` entries).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from ...errors import InputError
from .ekf import Estimate, EstimatorInput, FilterSettings, run_ekf, run_iekf
from .ml import run_ml
from .ukf import run_ukf


@dataclass(frozen=True)
class EstimatorKind:
    """One kind of estimator: its name, run function, the ``filter:`` keys of its keyword options
    (``{config key: keyword}``), one line for people, and whether its run takes ``on_pass``
    (:func:`~platcal.rigs.centrifuge.ekf.run_ekf`: the estimates of its first passes on the way)."""

    name: str
    run: Callable[..., Estimate]
    config_keys: dict = field(default_factory=dict)
    description: str = ""
    pass_snapshots: bool = False


KINDS: dict[str, EstimatorKind] = {
    "ekf": EstimatorKind("ekf", run_ekf, {"warmup_s": "warmup_s"},
                         "the paper's EKF, filter.passes passes (after a warm-up pass over the first "
                         "filter.warmup_s of each position when set)", pass_snapshots=True),
    "iekf": EstimatorKind("iekf", run_iekf, {"iterations": "iterations", "iterate_tol": "tol",
                                             "iterate_s": "until_s", "iterate_ratio": "ratio"},
                          "iterated EKF: each update relinearised (Gauss-Newton)", pass_snapshots=True),
    "ukf": EstimatorKind("ukf", run_ukf, {"ukf_sigma_points": "sigma_points", "ukf_alpha": "alpha",
                                          "ukf_beta": "beta", "ukf_kappa": "kappa"},
                         "unscented Kalman filter, filter.passes passes"),
    "ml": EstimatorKind("ml", run_ml, {"ml_max_iter": "max_iter", "ml_tol": "tol", "ml_start": "start",
                                       "ml_damping": "damping", "ml_coarse": "coarse", "ml_final": "final"},
                        "batch maximum likelihood (MAP): Gauss-Newton over the whole record, ARW whitened"),
}
"""The registered kinds, in the order they are listed (``Rig.estimators``, benchmarks)."""


def kind_names() -> tuple[str, ...]:
    return tuple(KINDS)


def check_kind(name: str, field_name: str = "filter.estimator") -> EstimatorKind:
    """The kind called ``name``; InputError naming ``field_name`` and the kinds otherwise."""
    if name not in KINDS:
        raise InputError(field_name, f"unknown estimator kind {name!r}; use one of {list(KINDS)}")
    return KINDS[name]


def options_from_filter(fcfg: dict) -> tuple:
    """``(keyword, value)`` options of the kind ``fcfg['estimator']`` from a validated ``filter:``
    section (keys that are null or absent keep the run function's default)."""
    kind = check_kind(str(fcfg.get("estimator", "ekf")))
    out = []
    for key, kw in kind.config_keys.items():
        if fcfg.get(key) is not None:
            v = fcfg[key]
            out.append((kw, v))
    return tuple(out)


def run_estimator(data: EstimatorInput, settings: FilterSettings, on_pass=None) -> Estimate:
    """Run the estimator ``settings.estimator`` with its ``settings.estimator_options``;
    ``on_pass`` (a kind with ``pass_snapshots``) as :func:`~platcal.rigs.centrifuge.ekf.run_ekf`'s."""
    kind = check_kind(settings.estimator)
    if on_pass is None:
        return kind.run(data, settings, **dict(settings.estimator_options))
    if not kind.pass_snapshots:
        raise ValueError(f"the {kind.name} estimator gives no estimates of its first passes (on_pass)")
    return kind.run(data, settings, on_pass=on_pass, **dict(settings.estimator_options))
