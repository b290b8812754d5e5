"""File I/O of the jobs: features, JSON rows and .npz arrays; outputs are written atomically (a temporary file
beside the target, then a rename), so no half-written output is left."""

import contextlib
import json
import math
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .errors import DataFileError


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path in the target's folder; on success rename it to ``path``, else delete it.

    The temporary name keeps the target's suffix, so writers that add a suffix (numpy.savez) are not confused.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(
            tmp, 0o666 & ~_umask()
        )  # mkstemp creates 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def read_npz(path, keys=None):
    """All arrays (or ``keys``) of a job's ``.npz`` output as a dict of arrays, without pickles.

    Raises ``DataFileError`` naming the file (unreadable, truncated, not an .npz, or without one of ``keys``),
    with what to do: delete it and rerun, so that Snakemake rebuilds it.
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            names = f.files if keys is None else list(keys)
            missing = [k for k in names if k not in f.files]
            if missing:
                raise DataFileError(
                    path,
                    f"missing array(s) {missing}; it has {sorted(f.files)}; delete it and "
                    "rerun to rebuild it",
                )
            return {k: f[k] for k in names}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DataFileError(
            path,
            f"cannot read as .npz ({type(exc).__name__}: {exc}); delete it and rerun to rebuild it",
        ) from exc


def load_features(path):
    """Read a features file (``X`` frames x features, ``Y`` frames x angles in degrees) and check it."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "features file does not exist")
    data = read_npz(path)
    for key in ("X", "Y"):
        if key not in data:
            raise DataFileError(path, f"missing array {key!r}; it has {sorted(data)}")
    X = np.asarray(data["X"], dtype=float)
    Y = np.asarray(data["Y"], dtype=float)
    if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise DataFileError(
            path, f"X and Y must be 2-D with the same number of rows; got {X.shape} and {Y.shape}"
        )
    for key, a in (("X", X), ("Y", Y)):
        bad = ~np.isfinite(a)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            raise DataFileError(
                path,
                f"{key} has {int(bad.sum())} non-finite value(s), first at row {r}, column {c} "
                f"({a[r, c]}); expected finite numbers",
            )
    out = {"X": X, "Y": Y}
    out["frames"] = np.asarray(data["frames"]) if "frames" in data else np.arange(X.shape[0])
    if "angle_names" in data:
        out["angle_names"] = [str(a) for a in data["angle_names"]]
    else:
        out["angle_names"] = [f"angle{i}" for i in range(Y.shape[1])]
    # Trial of each frame (motion-capture features of several trials; None for the .mat features).
    out["trials"] = np.asarray(data["trial_index"], dtype=int) if "trial_index" in data else None
    # Column of the root's heading angle (2 for the authors' features, 1 for the CMU BVH joint maps).
    out["heading_column"] = int(data["heading_column"]) if "heading_column" in data else 2
    # The data set's other records (source, activity, checksums, ...).
    out["meta"] = {k: v for k, v in data.items() if k not in ("X", "Y", "frames", "angle_names")}
    return out


def read_csv(path, what, **kwargs):
    """``pandas.read_csv(path, **kwargs)``; DataFileError naming the file and ``what`` it should hold (e.g. "the
    aggregate table") if it cannot be read as CSV."""
    import pandas as pd

    try:
        return pd.read_csv(path, **kwargs)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise DataFileError(path, f"cannot read {what} ({exc}); expected a CSV file") from exc


def write_json(path, obj):
    """Write ``obj`` as sorted, indented JSON, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(to_builtin(obj), indent=1, sort_keys=True) + "\n")


def write_arrays(path, arrays):
    """Write arrays to ``path`` (.npz, compressed), atomically."""
    with atomic_path(path) as tmp:
        np.savez_compressed(tmp, **arrays)


def read_json(path):
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DataFileError(path, f"cannot read JSON ({exc})") from exc


def to_builtin(v):
    """JSON-friendly copy of numbers, arrays, dicts and lists."""
    if isinstance(v, dict):
        return {str(k): to_builtin(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [to_builtin(x) for x in v]
    if isinstance(v, np.ndarray):
        return to_builtin(v.tolist())
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
