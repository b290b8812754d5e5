"""Data sets: (X, Y, frames, angle_names) per activity, from the authors' feature files or rendered from mocap.

Two kinds of data set entry (see config/datasets.yaml):

* ``format: mat`` -- a MATLAB file with a feature matrix ``X`` (frames x D) and a pose matrix ``Y``
  (frames x angles, degrees), e.g. the authors' group's precomputed silhouette features (Zolfaghari et al.,
  "3D human pose estimation from image using couple sparse coding", MVA 2014; their ``Run.m`` uses the first
  600 frames and drops the 3 root-translation columns of ``Y``).
* ``format: bvh`` / ``amc`` -- CMU motion capture trials (concatenated), turned into poses by
  :func:`bsrbench.mocap.load_motion`, rendered as silhouettes, described by shape contexts and encoded as a
  histogram over a codebook of shape contexts (the paper's Section IV, following Agarwal & Triggs, PAMI 2006).

Every loader verifies SHA-256 checksums when a checksum list is given, and every writer writes atomically.
"""

import functools
import hashlib
import sys
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DataFileError, InputError
from .io import atomic_path
from .seeds import derive_seed

# --------------------------------------------------------------------------------------------------- checksums


def sha256_file(path):
    """Hex SHA-256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_checksums(sums_path):
    """``{absolute path: hex digest}`` from a ``sha256sum``-style list (paths relative to the list's folder)."""
    sums_path = Path(sums_path)
    if not sums_path.is_file():
        raise DataFileError(
            sums_path, "checksum list not found (expected lines '<sha256>  <file>')"
        )
    out = {}
    for k, line in enumerate(sums_path.read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = line.split(None, 1)
        if len(parts) != 2 or len(parts[0]) != 64:
            raise DataFileError(
                sums_path, f"line {k}: expected '<64 hex digits>  <file>', found {line!r}"
            )
        name = parts[1].strip().lstrip("*")
        out[str((sums_path.parent / name).resolve())] = parts[0].lower()
    return out


def verify_checksum(path, checksums):
    """Check ``path`` against ``checksums``.

    ``checksums``: None (no check), ``"sidecar"`` (the digest in ``<path>.sha256``, as written by the download
    helper), a path to a ``SHA256SUMS`` list, or a 64-hex-digit digest. Raises DataFileError naming the file,
    the expected and the actual digest.
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "file not found")
    if checksums is None:
        return
    if checksums == "sidecar":
        side = path.with_name(path.name + ".sha256")
        if not side.is_file():
            raise DataFileError(
                path, f"no checksum file {side.name} beside it (written by the download rule)"
            )
        expected = side.read_text().split()[0].lower()
        where = str(side)
    elif (
        isinstance(checksums, str)
        and len(checksums) == 64
        and all(c in "0123456789abcdefABCDEF" for c in checksums)
    ):
        expected, where = checksums.lower(), "the configuration"
    else:
        table = read_checksums(checksums)
        key = str(path.resolve())
        if key not in table:
            raise DataFileError(path, f"has no entry in the checksum list {checksums}")
        expected, where = table[key], str(checksums)
    actual = sha256_file(path)
    if actual != expected:
        raise DataFileError(
            path, f"checksum mismatch: expected sha256 {expected} (from {where}), got {actual}"
        )


# ------------------------------------------------------------------------------------------------ feature sets


@dataclass
class FeatureSet:
    """One activity's data: ``X`` (F, D) features, ``Y`` (F, A) pose angles in degrees, ``frames`` (F,) index
    of each row in its source, ``angle_names`` (A,), and ``meta`` (strings/arrays saved alongside)."""

    X: np.ndarray
    Y: np.ndarray
    frames: np.ndarray
    angle_names: list
    meta: dict = field(default_factory=dict)


def check_features(
    X, Y, source, n_features=None, n_angles=None, names=("X", "Y"), rows=None, y_column_offset=0
):
    """Raise InputError naming ``source`` unless X and Y are finite 2-D arrays with matching rows.

    The error for a non-finite value gives its row and column in the file when X and Y are a selection of it:
    ``names`` are the two arrays' names (keys) in ``source``, ``rows[r]`` the file's row of row ``r`` and
    ``y_column_offset`` the number of leading columns of Y dropped after reading (all 0-based).
    """
    X = np.asarray(X)
    Y = np.asarray(Y)
    if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise InputError(
            f"{source}: X and Y must be 2-D with the same number of rows; got {X.shape} and {Y.shape}"
        )
    if n_features is not None and X.shape[1] != n_features:
        raise InputError(f"{source}: X has {X.shape[1]} columns; expected {n_features}")
    if n_angles is not None and Y.shape[1] != n_angles:
        raise InputError(f"{source}: Y has {Y.shape[1]} columns; expected {n_angles}")
    for name, a, offset in ((names[0], X, 0), (names[1], Y, int(y_column_offset))):
        bad = ~np.isfinite(a)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            row = int(r) if rows is None else int(np.asarray(rows)[r])
            where = "" if rows is None and not offset else " of the file (0-based)"
            raise InputError(
                f"{source}: {name} has {int(bad.sum())} non-finite value(s), first at row {row}, column "
                f"{int(c) + offset}{where} ({a[r, c]}); expected finite numbers"
            )


def select_frames(n_available, n_frames, how, source="<data>", fewer="error"):
    """Row indices: ``"first"`` -> ``0 .. n_frames-1``; ``"spread"`` -> ``round(linspace(0, n_available-1,
    n_frames))`` (evenly over all usable frames).

    With fewer than ``n_frames`` available: ``fewer="error"`` raises InputError; ``fewer="use_all"`` keeps all
    ``n_available`` (``"first"`` only: a spread over fewer frames than asked would repeat frames).
    """
    n_available, n_frames = int(n_available), int(n_frames)
    if n_frames < 1:
        raise InputError(f"{source}: n_frames must be >= 1; got {n_frames}")
    if how not in ("first", "spread"):
        raise InputError(f"{source}: frame_selection must be 'first' or 'spread'; got {how!r}")
    if fewer not in FEWER_FRAMES:
        raise InputError(f"{source}: fewer_frames must be one of {FEWER_FRAMES}; got {fewer!r}")
    if n_available < n_frames:
        if fewer == "use_all" and how == "first" and n_available >= 1:
            return np.arange(n_available)
        raise InputError(
            f"{source}: has {n_available} usable frames but n_frames = {n_frames} were asked for "
            f"(add trials to concatenate, lower n_frames, or set fewer_frames: use_all with frame_selection: first)"
        )
    if how == "first":
        return np.arange(n_frames)
    return np.round(np.linspace(0, n_available - 1, n_frames)).astype(int)


#: What a data set does when its trials give fewer frames than ``n_frames``.
FEWER_FRAMES = ("error", "use_all")


def step_frames(trial_frames, frame_step):
    """Indices of the frames whose index in their own file is a multiple of ``frame_step``.

    ``trial_frames`` (F,): each frame's index within its trial file (:attr:`bsrbench.mocap.Motion.trial_frames`).
    With ``frame_step = 4`` a 120 fps trial becomes 30 fps at the file's frames 0, 4, 8, ..., the frames the
    authors' group's files hold (resources/paper-features/README.md, "alignment"); frames dropped by
    ``skip_frames`` stay dropped.
    """
    if (
        isinstance(frame_step, bool)
        or not isinstance(frame_step, (int, np.integer))
        or frame_step < 1
    ):
        raise InputError(f"frame_step must be an integer >= 1; got {frame_step!r}")
    return np.flatnonzero(np.asarray(trial_frames, dtype=int) % int(frame_step) == 0)


def frame_protocol(frame_selection, frame_step, n_frames, frame_time=None):
    """One sentence naming how a data set's frames were chosen (stored with the features; used in tables)."""
    rate = ""
    if frame_time:
        rate = (
            f" of the {1.0 / frame_time:.0f} fps trials ({1.0 / (frame_time * frame_step):.0f} fps)"
        )
    step = (
        f"one frame in {frame_step}{rate}, "
        if frame_step > 1
        else (f"all frames{rate}, " if rate else "")
    )
    if frame_selection == "first":
        return f"{step}trials concatenated in order, first {n_frames} frames"
    return f"{step}trials concatenated in order, {n_frames} frames spread evenly over all"


def bvh_header(path):
    """``(frames, frame_time)`` from a BVH file's ``Frames:`` and ``Frame Time:`` lines (nothing else is read),
    or None when the file is missing, not BVH, or the lines are absent or malformed."""
    p = Path(path)
    if p.suffix.lower() != ".bvh" or not p.is_file():
        return None
    n = None
    with open(p, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            t = line.strip()
            try:
                if t.startswith("Frames:"):
                    n = int(t.split()[1])
                elif t.startswith("Frame Time:"):
                    return (n, float(t.split()[2])) if n is not None else None
            except (IndexError, ValueError):
                return None
    return None


def _amc_frames(path):
    """Frames of an AMC file (:func:`bsrbench.mocap.asf.amc_frame_count`), or None when it is missing; kept
    per file version (the configuration asks again for every table that names the data set)."""
    p = Path(path)
    if not p.is_file():
        return None
    stat = p.stat()
    return _amc_frames_cached(str(p.resolve()), stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=64)
def _amc_frames_cached(path, mtime_ns, size):
    from .mocap.asf import amc_frame_count

    return amc_frame_count(path)


def motion_frames(path):
    """Frames of one motion file, from a BVH header (:func:`bvh_header`) or an AMC file's frame-number lines;
    None when the file is missing, of another kind, or its header is malformed."""
    if Path(path).suffix.lower() == ".amc":
        return _amc_frames(path)
    h = bvh_header(path)
    return None if h is None else h[0]


def motion_frame_time(path):
    """Frame time (s) of one motion file: a BVH header's ``Frame Time:``, CMU's 1/120 s for an AMC file
    (:data:`bsrbench.mocap.asf.AMC_FRAME_TIME`; AMC files carry none), None otherwise."""
    from .mocap.asf import AMC_FRAME_TIME

    if Path(path).suffix.lower() == ".amc":
        return AMC_FRAME_TIME
    h = bvh_header(path)
    return None if h is None else h[1]


def count_motion_frames(paths, skip_frames=1, frame_step=1):
    """Frames that :func:`prepare_motion` would have to choose from, counted without parsing the motion: from
    the BVH headers, or the frame-number lines of AMC files (:func:`motion_frames`); None when a file is
    missing or neither."""
    total = 0
    for p in paths:
        n = motion_frames(p)
        if n is None:
            return None
        total += len(step_frames(np.arange(int(skip_frames), n), frame_step))
    return total


def load_feature_mat(
    path,
    n_frames=600,
    frame_selection="first",
    drop_y_columns=3,
    x_key="X",
    y_key="Y",
    checksums=None,
    angle_names=None,
    first_frame=0,
    frame_step=1,
    fewer_frames="error",
):
    """Load a .mat file holding ``X`` and ``Y`` (one row per frame) as a :class:`FeatureSet`.

    The first ``drop_y_columns`` columns of Y are dropped (the authors' files carry the root translation there).
    Frames: the rows ``first_frame, first_frame + frame_step, ...``, of which :func:`select_frames` keeps
    ``n_frames`` (``fewer_frames``: when fewer are left). ``checksums``: see :func:`verify_checksum`.
    ``angle_names``: names of the kept Y columns (default ``angle01`` ...).
    """
    import scipy.io

    path = Path(path)
    verify_checksum(path, checksums)
    try:
        m = scipy.io.loadmat(path)
    except Exception as e:  # scipy raises several types for a non-MAT file
        raise DataFileError(path, f"cannot be read as a MATLAB .mat file ({e})") from None
    for key in (x_key, y_key):
        if key not in m:
            have = sorted(k for k in m if not k.startswith("__"))
            raise DataFileError(
                path,
                f"has no variable {key!r} (variables: {have}); expected {x_key!r} and {y_key!r}",
            )
    X = np.asarray(m[x_key], dtype=float)
    Y = np.asarray(m[y_key], dtype=float)
    if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise DataFileError(
            path, f"{x_key} {X.shape} and {y_key} {Y.shape} must be 2-D with equal rows"
        )
    if not 0 <= drop_y_columns < Y.shape[1]:
        raise InputError(
            f"{path}: drop_y_columns={drop_y_columns} but {y_key} has {Y.shape[1]} columns"
        )
    Y = Y[:, drop_y_columns:]
    rows = np.arange(int(first_frame), X.shape[0], int(frame_step))
    if rows.size == 0:
        raise InputError(f"{path}: first_frame={first_frame} but the file has {X.shape[0]} rows")
    idx = rows[select_frames(rows.size, n_frames, frame_selection, str(path), fewer=fewer_frames)]
    X, Y = X[idx], Y[idx]
    check_features(X, Y, str(path), names=(x_key, y_key), rows=idx, y_column_offset=drop_y_columns)
    if angle_names is None:
        angle_names = [f"angle{k + 1:02d}" for k in range(Y.shape[1])]
    elif len(angle_names) != Y.shape[1]:
        raise InputError(f"{path}: {len(angle_names)} angle_names for {Y.shape[1]} pose columns")
    return FeatureSet(
        X, Y, idx, list(angle_names), {"files": [str(path)], "sha256": [sha256_file(path)]}
    )


def count_mat_rows(path, x_key="X"):
    """Rows of the matrix ``x_key`` of a .mat file, read from its header (None if it cannot be read)."""
    import scipy.io

    try:
        shapes = {name: shape for name, shape, _ in scipy.io.whosmat(path)}
    except Exception:  # scipy raises several types for a missing or non-MAT file
        return None
    shape = shapes.get(x_key)
    return int(shape[0]) if shape else None


def save_features(path, fs):
    """Write a FeatureSet as ``.npz`` (X, Y, frames, angle_names + meta) atomically, after checking it."""
    check_features(fs.X, fs.Y, f"features for {path}")
    arrays = {
        "X": np.asarray(fs.X, dtype=float),
        "Y": np.asarray(fs.Y, dtype=float),
        "frames": np.asarray(fs.frames, dtype=int),
        "angle_names": np.array(fs.angle_names, dtype=str),
    }
    for k, v in fs.meta.items():
        arrays[k] = np.asarray(v)
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def build_mat_features(
    mat_path,
    out_path,
    n_frames=600,
    frame_selection="first",
    drop_y_columns=3,
    x_key="X",
    y_key="Y",
    checksums=None,
    n_features=None,
    meta=None,
    first_frame=0,
    frame_step=1,
    fewer_frames="error",
):
    """Load a feature .mat (verified) and write it as a features ``.npz``. Returns the FeatureSet."""
    fs = load_feature_mat(
        mat_path,
        n_frames,
        frame_selection,
        drop_y_columns,
        x_key,
        y_key,
        checksums,
        first_frame=first_frame,
        frame_step=frame_step,
        fewer_frames=fewer_frames,
    )
    check_features(fs.X, fs.Y, str(mat_path), n_features=n_features)
    fs.meta.update(meta or {})
    fs.meta.setdefault("heading_column", 2)
    save_features(out_path, fs)
    return fs


# ------------------------------------------------------------------------------------------------- mocap poses


def _heading_column(angle_names, pose_joints):
    """Index of the root's rotation about the vertical (y) axis, or -1."""
    name = f"{pose_joints[0]}_Yrotation"
    return angle_names.index(name) if name in angle_names else -1


def prepare_motion(
    paths,
    out_path,
    n_frames=600,
    frame_selection="spread",
    skeleton_kind=None,
    joint_map=None,
    drop_first_frame=True,
    asf=None,
    checksums=None,
    skip_frames=None,
    frame_step=1,
    fewer_frames="error",
):
    """Parse and concatenate trials, pick ``n_frames`` frames and save positions and poses to ``out_path``.

    Frames: ``skip_frames`` leading frames of every trial are dropped, then only the frames whose index in their
    file is a multiple of ``frame_step`` are kept (:func:`step_frames`; 4 turns the 120 fps CMU trials into the
    authors' 30 fps), then :func:`select_frames` picks ``n_frames`` of the concatenation (``fewer_frames``:
    "use_all" keeps all when there are fewer). The npz also records ``frame_step``, ``frame_selection``,
    ``n_frames_requested`` and ``frame_protocol`` (a sentence).

    The ``.npz`` holds ``positions`` (F, J, 3), ``parents``, ``joint_names``, ``angles`` (F, 57), ``angle_names``,
    ``frames`` (index among the concatenated usable frames), ``trial_ids``, ``trial_index``, ``trial_frames``,
    ``frame_time``, ``skeleton_kind``, ``pose_joints``, ``heading_column``. Returns the selected Motion.
    ``drop_first_frame``/``skip_frames``: leading frames dropped from every trial (see
    :func:`bsrbench.mocap.load_motion`).
    """
    from .mocap import load_motion

    paths = [Path(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths)]
    for p in paths:
        verify_checksum(p, checksums)
    if asf is not None:
        verify_checksum(asf, checksums)
    motion = load_motion(
        paths,
        skeleton_kind=skeleton_kind,
        joint_map=joint_map,
        drop_first_frame=drop_first_frame,
        asf=asf,
        skip_frames=skip_frames,
    )
    src = ", ".join(str(p) for p in paths)
    motion = motion.take(step_frames(motion.trial_frames, frame_step))
    idx = select_frames(motion.n_frames, n_frames, frame_selection, src, fewer=fewer_frames)
    sel = motion.take(idx)
    check_features(sel.positions.reshape(len(idx), -1), sel.angles, src)
    with atomic_path(out_path) as tmp:
        np.savez(
            tmp,
            positions=sel.positions,
            parents=sel.parents,
            joint_names=np.array(sel.joint_names, dtype=str),
            angles=sel.angles,
            angle_names=np.array(sel.angle_names, dtype=str),
            frames=sel.source_frames,
            trial_ids=np.array(sel.trial_ids, dtype=str),
            trial_index=sel.trial_index,
            trial_frames=sel.trial_frames,
            frame_time=sel.frame_time,
            skeleton_kind=sel.skeleton_kind,
            pose_joints=np.array(sel.pose_joints, dtype=str),
            heading_column=_heading_column(sel.angle_names, sel.pose_joints),
            files=np.array([str(p) for p in paths], dtype=str),
            sha256=np.array([sha256_file(p) for p in paths], dtype=str),
            frame_step=int(frame_step),
            frame_selection=str(frame_selection),
            n_frames_requested=int(n_frames),
            frame_protocol=frame_protocol(
                frame_selection, int(frame_step), int(n_frames), sel.frame_time
            ),
        )
    return sel


def _render_kwargs(render):
    kw = dict(render or {})
    if "image_size" in kw:
        kw["image_size"] = tuple(int(v) for v in kw["image_size"])
    return kw


def _descriptors(positions, parents, joint_names, render, n_points, seed):
    from .features import silhouette_descriptors
    from .render import render_silhouettes

    masks = render_silhouettes(positions, parents, joint_names, **_render_kwargs(render))
    return masks, silhouette_descriptors(masks, n_points=n_points, seed=seed)


def learn_codebook_from_trials(
    paths,
    out_path,
    frames_per_trial=60,
    n_centres=100,
    render=None,
    n_points=200,
    seed=0,
    drop_first_frame=True,
    checksums=None,
    asf=None,
    skip_frames=None,
):
    """Learn the shape-context codebook from the codebook trials only and save it (``centres``, ``trial_ids``).

    From each trial, ``frames_per_trial`` frames spread evenly over its usable frames are rendered; the shape
    contexts of all of them are clustered by k-means into ``n_centres`` centres
    (:func:`bsrbench.features.learn_codebook`). Deterministic for a seed.
    """
    from .features import learn_codebook
    from .mocap import load_motion

    paths = [Path(p) for p in paths]
    if not paths:
        raise InputError(
            "codebook: no trial files given (expected codebook.files in the configuration)"
        )
    descs = []
    for p in paths:
        verify_checksum(p, checksums)
        m = load_motion([p], drop_first_frame=drop_first_frame, asf=asf, skip_frames=skip_frames)
        m = m.take(select_frames(m.n_frames, frames_per_trial, "spread", str(p)))
        _, d = _descriptors(
            m.positions,
            m.parents,
            m.joint_names,
            render,
            n_points,
            derive_seed("codebook", p.stem, seed),
        )
        descs.extend(d)
    centres = np.asarray(learn_codebook(descs, n_centres=n_centres, seed=seed), dtype=float)
    if not np.all(np.isfinite(centres)):
        raise InputError(f"codebook learned from {len(paths)} trials has non-finite centres")
    with atomic_path(out_path) as tmp:
        np.savez(
            tmp,
            centres=centres,
            trial_ids=np.array([p.stem for p in paths], dtype=str),
            frames_per_trial=frames_per_trial,
            n_points=n_points,
            seed=seed,
        )
    return centres


def compute_mocap_features(
    motion_path,
    codebook_path,
    out_path,
    preview_path=None,
    render=None,
    n_points=200,
    soft=True,
    seed=0,
    name="",
    meta=None,
    preview_frames=16,
):
    """Render the selected frames of a prepared motion, describe and encode them, and save the features.

    Writes ``out_path`` (X = codebook histograms (F, n_centres), Y = the 57 angles, frames, angle_names, trial
    ids ...) and, if given, a montage of ``preview_frames`` silhouettes to ``preview_path``.
    """
    from .features import histogram_features
    from .render import save_montage

    motion_path, codebook_path = Path(motion_path), Path(codebook_path)
    for p in (motion_path, codebook_path):
        if not p.is_file():
            raise DataFileError(p, "file not found")
    with np.load(motion_path, allow_pickle=False) as z:
        mo = {k: z[k] for k in z.files}
    with np.load(codebook_path, allow_pickle=False) as z:
        if "centres" not in z:
            raise DataFileError(codebook_path, "has no array 'centres'")
        codebook = z["centres"]
    joint_names = [str(j) for j in mo["joint_names"]]
    masks, descs = _descriptors(
        mo["positions"],
        mo["parents"],
        joint_names,
        render,
        n_points,
        derive_seed("features", name, seed),
    )
    X = np.asarray(histogram_features(descs, codebook, soft=soft), dtype=float)
    Y = mo["angles"]
    check_features(X, Y, f"features of {motion_path}", n_features=codebook.shape[0])
    keep = (
        "trial_ids",
        "trial_index",
        "trial_frames",
        "frame_time",
        "skeleton_kind",
        "pose_joints",
        "heading_column",
        "files",
        "sha256",
        "frame_step",
        "frame_selection",
        "n_frames_requested",
        "frame_protocol",
    )
    info = {k: mo[k] for k in keep if k in mo}
    info.update(meta or {})
    fs = FeatureSet(X, Y, mo["frames"], [str(a) for a in mo["angle_names"]], info)
    if preview_path is not None:
        with atomic_path(preview_path) as tmp:
            save_montage(masks, tmp, n=preview_frames)
    save_features(out_path, fs)
    return fs


# --------------------------------------------------------------------------------------------- CMU download

CMU_BASE_URL = "http://mocap.cs.cmu.edu/subjects"


def _fetch(url, dest, expected_sha256=None, check=None, timeout=60):
    """Download ``url`` to ``dest`` atomically; check the digest if given and run ``check(tmp_path)`` (a parser)
    before the file takes its name, so a bad download leaves nothing behind. Returns the digest."""
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r:
            data = r.read()
    except (urllib.error.URLError, OSError, ValueError) as e:
        raise DataFileError(dest, f"download from {url} failed: {e}") from None
    digest = hashlib.sha256(data).hexdigest()
    if expected_sha256 and digest != expected_sha256.lower():
        raise DataFileError(
            dest, f"checksum mismatch for {url}: expected sha256 {expected_sha256}, got {digest}"
        )
    with atomic_path(dest) as tmp:
        Path(tmp).write_bytes(data)
        if check is not None:
            try:
                check(tmp)
            except DataFileError as e:
                raise DataFileError(
                    dest, f"downloaded from {url} but does not parse: {e}"
                ) from None
    return digest


def _write_sidecar(path, digest):
    side = Path(str(path) + ".sha256")
    with atomic_path(side) as tmp:
        Path(tmp).write_text(f"{digest}  {Path(path).name}\n")
    return side


def cmu_url(base_url, subject, trial=None):
    """``<base>/SS/SS_TT.amc`` for a trial or ``<base>/SS/SS.asf`` for a subject's skeleton (CMU's layout)."""
    s = f"{int(subject):02d}"
    name = f"{s}.asf" if trial is None else f"{s}_{int(trial):02d}.amc"
    return f"{base_url.rstrip('/')}/{s}/{name}"


def download_cmu_skeleton(subject, dest, base_url=CMU_BASE_URL, expected_sha256=None):
    """Download a CMU subject's ASF skeleton to ``dest``, check it (digest if given; else that it parses) and
    write ``<dest>.sha256``. Returns the digest."""
    from .mocap import parse_asf

    url = cmu_url(base_url, subject)
    digest = _fetch(url, dest, expected_sha256, check=parse_asf)
    _write_sidecar(dest, digest)
    print(f"downloaded {url} -> {dest} (sha256 {digest})", file=sys.stderr)
    return digest


def download_cmu_trial(subject, trial, dest, asf_path, base_url=CMU_BASE_URL, expected_sha256=None):
    """Download CMU trial ``SS_TT.amc`` to ``dest``, check it (digest if given; it must parse with the subject's
    ASF ``asf_path`` in any case) and write ``<dest>.sha256``. Returns the digest."""
    from .mocap import parse_amc

    url = cmu_url(base_url, subject, trial)
    digest = _fetch(url, dest, expected_sha256, check=lambda tmp: parse_amc(tmp, asf_path))
    _write_sidecar(dest, digest)
    print(f"downloaded {url} -> {dest} (sha256 {digest})", file=sys.stderr)
    return digest


def motion_map(entries):
    """{(source, activity): the distinct motion} of data-set entries ({(source, activity): entry} or the
    configuration's ``datasets`` mapping {source: {activity: entry}}): the entry's ``motion``, else the activity's
    name."""
    if not all(isinstance(k, tuple) for k in entries):
        entries = {
            (s, a): e
            for s, acts in entries.items()
            for a, e in (acts or {}).items()
            if isinstance(e, (dict, type(None)))
        }
    return {key: (e or {}).get("motion") or key[1] for key, e in entries.items()}
