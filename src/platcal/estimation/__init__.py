"""Estimation shared by the rigs: Kalman primitives for any small measurement dimension
(:mod:`.kalman`), filter consistency (:mod:`.consistency`: NEES, NIS bands), covariance-only
analysis (:mod:`.information`: correlation, the design criteria J, A, D, maxrel, Fisher
information, Cramer-Rao bound, rank and singular values) and estimators of fewer passes taken
from another's run (:mod:`.passes`). Nothing here names a rig."""
