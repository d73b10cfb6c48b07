"""File input and output: atomic writes (temp file, then rename) and YAML reading.

A failed or interrupted job therefore never leaves a half-written file under the final name.
"""

from __future__ import annotations

import os
import re
import tempfile
from contextlib import contextmanager
from pathlib import Path

import yaml


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path in the target's folder; rename it to ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_to_csv(df, path: str | os.PathLike, **kw) -> None:
    """``DataFrame.to_csv`` atomically (floats at full precision)."""
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=kw.pop("index", False), **kw)


def atomic_to_parquet(df, path: str | os.PathLike) -> None:
    """``DataFrame.to_parquet`` atomically."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=False)


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads ``1e4`` and ``1.0e4`` as floats (YAML 1.2 style)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."),
)


def read_yaml(text: str):
    """Parse YAML text, with floats such as ``1e4`` read as numbers."""
    return yaml.load(text, Loader=_Loader)


_FLOAT_RE = re.compile(r"^[-+]?(?:(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?|(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+))$")


def normalise_numbers(obj):
    """Read YAML 1.1 leftovers such as ``'1.0e4'`` (a string to PyYAML's and Snakemake's
    loaders) as floats, in place, as :func:`platcal.io.read_yaml` does; returns ``obj``."""
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for k, v in list(items):
        if isinstance(v, str) and _FLOAT_RE.match(v):
            obj[k] = float(v.replace("_", ""))
        elif isinstance(v, (dict, list)):
            normalise_numbers(v)
    return obj
