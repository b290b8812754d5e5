"""Atomic file output: write to a temporary file beside the target, then rename, so no half-written output."""

import contextlib
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np


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
    from .errors import DataFileError

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
