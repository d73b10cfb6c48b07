"""The figures' traces of the low-precision centrifuge's study on disk (an ``.npz``): written by
the workflow's rule ``lowprec_trace`` (:func:`.montecarlo.study_trace`), read by the report's
figures (:mod:`.report`). Apart from :mod:`.report` so that the trace job does not import the
figures' libraries, and from the Monte Carlo hooks' modules so that an edit here reruns no cell
(issue 22 item 4).
"""

from __future__ import annotations

import numpy as np

from ...io import atomic_path


def load_trace(path) -> dict:
    """The traces :func:`write_trace` wrote (0-d arrays back as Python numbers)."""
    with np.load(path, allow_pickle=False) as z:
        return {k: (z[k].item() if z[k].ndim == 0 else z[k]) for k in z.files}


def write_trace(trace: dict, path) -> None:
    """The figures' traces (:func:`.montecarlo.study_trace`) as an ``.npz``, atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **trace)
