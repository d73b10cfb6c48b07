"""File input and output: atomic writes (temp file, then rename) and YAML reading.

A failed or interrupted job therefore never leaves a half-written file under the final name.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from .errors import InputError, WriteError


def _umask() -> int:
    """The process umask (read by setting and restoring it: there is no getter)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def remove_orphans(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files (``.<name>.*.part``) that a killed writer of ``path`` left.

    Only the temporaries of this one target are touched, so a rerun tidies what its own
    earlier, interrupted run left beside the file it writes.
    """
    path = Path(path)
    if not path.parent.is_dir():
        return []
    gone = []
    for orphan in path.parent.glob(f".{glob_escape(path.name)}.*.part"):
        # mkstemp's random part holds no dot: ".rec.csv.truth.json.<random>.part" is the temporary
        # of another file written in the same step (platcal.records.write_record), not an orphan
        if "." in orphan.name[len(path.name) + 2:-len(".part")]:
            continue
        try:
            orphan.unlink()
            gone.append(orphan)
        except OSError:
            pass
    return gone


def glob_escape(name: str) -> str:
    """``name`` with the glob metacharacters quoted."""
    return re.sub(r"([*?\[])", r"[\1]", name)


def _raise_write_error(exc: BaseException, path: Path) -> None:
    """Turn an OSError of a write (ENOSPC, EACCES, ...) into a :class:`WriteError` naming the final
    ``path``, the temporaries already removed; anything else is left to propagate as it is."""
    if isinstance(exc, OSError) and not isinstance(exc, WriteError):
        raise WriteError(exc.errno, exc.strerror or str(exc), str(path)) from exc


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path in the target's folder; rename it to ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_orphans(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        # mkstemp makes 0600; the final file gets the mode open() would give it
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        _raise_write_error(exc, path)
        raise


@contextmanager
def atomic_files(folder: str | os.PathLike):
    """Write several files of one result folder so that they land together or not at all.

    Yields ``tmp(name) -> Path``: a temporary path in ``folder`` for the file ``name``. When the
    block ends without error every temporary is renamed to its final name (in the order asked
    for, so name the file that marks completion, e.g. ``summary.json``, last); on error every
    temporary is removed and no final name is touched. Other files in ``folder`` are left alone.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    temps: list[tuple[Path, Path]] = []

    def tmp(name: str) -> Path:
        final = folder / name
        remove_orphans(final)
        fd, t = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".part", dir=folder)
        os.close(fd)
        temps.append((Path(t), final))
        return Path(t)

    try:
        yield tmp
        mode = 0o666 & ~_umask()
        for t, _ in temps:
            os.chmod(t, mode)
        for t, final in temps:
            os.replace(t, final)
    except BaseException as exc:
        for t, _ in temps:
            t.unlink(missing_ok=True)
        # name the file being written (the last asked for), else the folder
        _raise_write_error(exc, temps[-1][1] if temps else folder)
        raise


@contextmanager
def atomic_folder(folder: str | os.PathLike):
    """Fill a result folder so that it appears whole or not at all.

    Yields a temporary folder beside ``folder``; when the block ends without error it is renamed
    to ``folder``, which must not exist or be empty (a Snakemake ``directory()`` output: Snakemake
    removes it before the job). On error the temporary folder and its files are removed.
    """
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".part", dir=folder.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        if folder.is_dir():
            folder.rmdir()  # empty (made by the caller): rename cannot replace a folder otherwise
        os.replace(tmp, folder)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        _raise_write_error(exc, folder)
        raise


def check_writable(path: str | os.PathLike, field: str, folder: bool = False) -> None:
    """Refuse (InputError naming ``field``) an output path that cannot be written, before any work.

    ``path`` is a file to write (``folder=False``) or a folder to fill. The nearest existing
    ancestor must be a folder in which a file can be created (probed with a temporary file that
    is removed at once, so read-only folders and file systems are found whoever runs); an
    existing ``path`` must be of the right kind. Nothing is left behind.
    """
    path = Path(path)
    if path.exists():
        if folder and not path.is_dir():
            raise InputError(field, f"{path} exists and is not a folder; give a folder name")
        if not folder and path.is_dir():
            raise InputError(field, f"{path} is a folder; give a file name")
    probe_dir = path if folder and path.is_dir() else path.parent
    while not probe_dir.exists():
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir():
        raise InputError(field, f"{probe_dir} is a file, so {path} cannot be created under it")
    try:
        fd, probe = tempfile.mkstemp(prefix=".platcal-probe.", dir=probe_dir)
    except OSError as exc:
        raise InputError(field, f"cannot write in {probe_dir}: {exc.strerror}") from None
    os.close(fd)
    os.unlink(probe)


def json_safe(obj):
    """``obj`` with NaN and infinities as ``None`` and numpy scalars as plain numbers (valid JSON)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "tolist") and getattr(obj, "ndim", 0) > 0:
        return json_safe(obj.tolist())
    if hasattr(obj, "item") and callable(obj.item) and getattr(obj, "ndim", 1) == 0:
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def json_text(obj) -> str:
    """Strict JSON text of ``obj`` (NaN/inf written as ``null``), indented, with a final newline."""
    return json.dumps(json_safe(obj), indent=2, allow_nan=False) + "\n"


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_to_csv(df, path: str | os.PathLike, **kw) -> None:
    """``DataFrame.to_csv`` atomically (floats at full precision)."""
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=kw.pop("index", False), **kw)


CSV_BLOCK_VALUES = 100_000
"""Values converted to Python and written at a time by :func:`write_csv` (a block of rows of the
table's width, about 3 MB of Python floats): a long table (a 6 h history) is not held as Python
floats and text beside its arrays. Blocks of 10 000 rows held 31 MB for the centrifuge's 97-column
history (issue 22 item 3)."""


def write_csv(path: str | os.PathLike, columns: dict, index: tuple[str, list] | None = None,
              float_format: str | None = None) -> None:
    """Write ``columns`` (name -> values, equal lengths) to ``path`` as the CSV text
    ``DataFrame.to_csv`` writes, without pandas: ``index`` (label, values) first as
    ``to_csv(index=True)`` of a named index; floats at full precision (``repr``) or
    ``float_format`` (``"%.6g"``), NaN and None empty, text quoted only when it holds a comma,
    quote or line break; UTF-8, ``\\n`` line ends. An identify writes its tables through this, so
    it never loads pandas (issue 22 item 3: pandas is some 40 MB of a streamed identify's floor).
    Not atomic by itself: call it on a path of :func:`atomic_files` or use :func:`atomic_write_csv`."""
    names = ([index[0]] if index else []) + [str(c) for c in columns]
    cols = ([list(index[1])] if index else []) + list(columns.values())
    write_csv_blocks(path, names, [cols], float_format)


def write_csv_blocks(path: str | os.PathLike, names: list[str], blocks, float_format: str | None = None) -> None:
    """:func:`write_csv` of a table that comes in blocks of rows: ``names`` the header,
    ``blocks`` an iterable of lists of columns (in ``names``' order, equal lengths within a
    block), written as they come, so a long table (a streamed identify's history, issue 22 item 3)
    is never held whole. The same text as :func:`write_csv` of the blocks joined."""
    with open(path, "w", encoding="utf-8", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(names)
        for cols in blocks:
            rows = len(cols[0]) if cols else 0
            step = max(1, CSV_BLOCK_VALUES // max(1, len(cols)))
            for a in range(0, rows, step):
                block = [c[a:a + step].tolist() if isinstance(c, np.ndarray) else list(c[a:a + step]) for c in cols]
                writer.writerows(["" if v is None or (isinstance(v, float) and math.isnan(v))
                                  else float_format % v if float_format and isinstance(v, float) else v for v in row]
                                 for row in zip(*block))


def atomic_write_csv(path: str | os.PathLike, columns: dict, index: tuple[str, list] | None = None,
                     float_format: str | None = None) -> None:
    """:func:`write_csv` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        write_csv(tmp, columns, index, float_format)


def atomic_to_parquet(df, path: str | os.PathLike) -> None:
    """``DataFrame.to_parquet`` atomically."""
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=False)


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """SafeLoader that also reads ``1e4`` and ``1.0e4`` as floats (YAML 1.2 style) and refuses a
    key given twice in one mapping (plain PyYAML keeps the last silently). On libyaml's parser
    when PyYAML has it (the same documents, about 10x faster: every job and the workflow's start
    read the configs and schemas)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, (str, int, float, bool)) or key is None:
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        "while reading a mapping", node.start_mark, f"found the key {key!r} twice", key_node.start_mark)
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."),
)


def read_config(path, field: str = "--config") -> dict:
    """The raw mapping of a YAML config file; InputError naming ``field`` (the option or the
    index entry that gave the path) if it cannot be read or parsed. The one config reader."""
    try:
        return read_yaml(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(field, f"no such file: {path}") from None
    except IsADirectoryError:
        raise InputError(field, f"{path} is a folder; give a YAML config file") from None
    except OSError as exc:
        raise InputError(field, f"cannot read {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise InputError(field, f"{path} is not UTF-8 text (byte {exc.start} cannot be decoded); "
                         "a config is a UTF-8 YAML file") from None
    except (ValueError, yaml.YAMLError) as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        problem = getattr(exc, "problem", None)
        raise InputError(field, f"{path} is not valid YAML{at} ({problem or exc.__class__.__name__}); "
                         "a config is a UTF-8 YAML file") from None


def read_yaml(text: str):
    """Parse YAML text, with floats such as ``1e4`` read as numbers."""
    return yaml.load(text, Loader=_Loader)


_FLOAT_RE = re.compile(r"^[-+]?(?:(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?|(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+))$")


def sorted_mapping(obj):
    """A copy of ``obj`` with every mapping's keys sorted, at every depth (lists keep their
    order). For a Snakemake param built by merging overrides into a config: Snakemake compares a
    param's ``repr``, which follows key order, and a merge appends keys the base lacks."""
    if isinstance(obj, dict):
        return {k: sorted_mapping(obj[k]) for k in sorted(obj)}
    if isinstance(obj, list):
        return [sorted_mapping(v) for v in obj]
    return obj


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
