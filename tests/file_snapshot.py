"""What a folder holds, to check that a refused command wrote nothing."""

import os


def snapshot(folder) -> dict:
    """Every file and folder under ``folder`` with its bytes (None for folders)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for d in dirs:
            out[os.path.relpath(os.path.join(root, d), folder)] = None
        for f in files:
            p = os.path.join(root, f)
            with open(p, "rb") as fh:
                out[os.path.relpath(p, folder)] = fh.read()
    return out
