"""Seeds: one ``numpy.random.SeedSequence`` per (rig, scheme or case, noise, replicate).

Keys are stable 32-bit integers of names (SHA-256), never Python's salted ``hash`` and never
``seed + i``, so a replicate's numbers do not depend on the batch it runs in, the number of
threads, jobs or cores, or the order of the jobs.
"""

from __future__ import annotations

import hashlib

import numpy as np


def stable_key(name: str) -> int:
    """A stable 32-bit integer key of a name (SHA-256; independent of PYTHONHASHSEED)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:4], "big")


def seed_sequence(entropy: int, *keys) -> np.random.SeedSequence:
    """``SeedSequence(entropy, spawn_key=keys)``; string keys become :func:`stable_key`."""
    spawn = tuple(stable_key(k) if isinstance(k, str) else int(k) for k in keys)
    return np.random.SeedSequence(entropy=int(entropy), spawn_key=spawn)
