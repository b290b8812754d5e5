"""The authors' group's pose files: their skeleton, their frames in the CMU trials, their angle convention.

The feature files in ``resources/paper-features`` (``x09.mat``, ``x131.mat``, ...; Zolfaghari et al., MVA 2014,
repository mzolfaghari/3D-human-pose-estimation) hold a pose matrix ``Y`` (frames x 60). The group's
``matrix_to_bvh_Edited.m`` writes such rows, as they are, as the motion rows of its ``hierarchy2.bvh``: 19 joints,
the root with ``Xposition Yposition Zposition Zrotation Xrotation Yrotation`` and every other joint with
``Zrotation Xrotation Yrotation`` (Euler angles in degrees, first channel outermost), at 30 fps
(``Frame Time: 0.033333``). So the 57 angles are the local rotations of that skeleton, and a pose row becomes
3-D joint positions by forward kinematics on it (:func:`hsc_positions`).

This module

* describes that skeleton (:data:`HSC_JOINTS`, :func:`hsc_skeleton`; joint names, parents and offsets as listed
  in ``hierarchy2.bvh``) and the role of each of its joints in our 19-joint maps (:data:`HSC_ROLE_ORDER`);
* finds the CMU trial and frame each row of an authors' file comes from (:func:`align_rows`), by the root
  trajectory (the first 3 columns of ``Y``): each trial, taken at every 4th frame of its 120 fps file with
  one of the 4 phases, is slid along the rows, and the window whose per-axis affine fit leaves the smallest
  residual wins;
* relates their joint rotations to ours on aligned frames (:func:`fit_joint_rotations`): for every joint,
  constant rotations ``A`` and ``B`` with ``R_theirs ~ A @ R_ours @ B`` (alternating orthogonal Procrustes), so
  that our poses can be written in their convention (:func:`ours_to_hsc_angles`), and reports the residual;
* correlates their 57 columns with our 57 (:func:`column_correlations`).
"""

import numpy as np
from scipy.spatial.transform import Rotation

from .errors import InputError
from .metrics import wrap_degrees
from .mocap.skeleton import Skeleton, euler_matrix, forward_kinematics

#: Joints of ``hierarchy2.bvh`` (mzolfaghari/3D-human-pose-estimation) in file order, with parent and offset.
#: End sites are named ``<joint>_End`` as :func:`bsrbench.mocap.parse_bvh` names them.
_HIERARCHY = (
    (
        "Hips",
        None,
        (0.0, 0.0, 0.0),
    ),  # the file's root offset (-24.8, 33.0, 8.8) only moves the figure
    ("LeftHip", "Hips", (3.43, 0.0, 0.0)),
    ("LeftKnee", "LeftHip", (0.0, -18.47, 0.0)),
    ("LeftAnkle", "LeftKnee", (0.0, -17.95, 0.0)),
    ("LeftAnkle_End", "LeftAnkle", (0.0, -3.12, 0.0)),
    ("RightHip", "Hips", (-3.43, 0.0, 0.0)),
    ("RightKnee", "RightHip", (0.0, -18.47, 0.0)),
    ("RightAnkle", "RightKnee", (0.0, -17.95, 0.0)),
    ("RightAnkle_End", "RightAnkle", (0.0, -3.12, 0.0)),
    ("Chest", "Hips", (0.0, 4.57, 0.0)),
    ("CS_BVH", "Chest", (0.0, 6.57, 0.0)),
    ("LeftCollar", "CS_BVH", (1.06, 4.19, 1.76)),
    ("LeftShoulder", "LeftCollar", (5.81, 0.0, 0.0)),
    ("LeftElbow", "LeftShoulder", (0.0, -12.08, 0.0)),
    ("LeftWrist", "LeftElbow", (0.0, -9.82, 0.0)),
    ("LeftWrist_End", "LeftWrist", (0.0, -7.37, 0.0)),
    ("RightCollar", "CS_BVH", (-1.06, 4.19, 1.76)),
    ("RightShoulder", "RightCollar", (-6.06, 0.0, 0.0)),
    ("RightElbow", "RightShoulder", (0.0, -11.08, 0.0)),
    ("RightWrist", "RightElbow", (0.0, -9.82, 0.0)),
    ("RightWrist_End", "RightWrist", (0.0, -7.14, 0.0)),
    ("Neck", "CS_BVH", (0.0, 4.05, 0.0)),
    ("Head", "Neck", (0.0, 5.19, 0.0)),
    ("Head_End", "Head", (0.0, 4.14, 0.0)),
)

#: The 19 rotating joints, in the order of the 57 angle columns (3 per joint: Z, X, Y rotation).
HSC_JOINTS = [n for n, _, _ in _HIERARCHY if not n.endswith("_End")]
#: Euler order of every joint's three columns (the first is the outermost rotation).
HSC_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
#: Names of the 57 angle columns, ``<joint>_<channel>``.
HSC_ANGLE_NAMES = [f"{j}_{c}" for j in HSC_JOINTS for c in HSC_CHANNELS]
#: The hsc joints in the role order of :data:`bsrbench.mocap.JOINT_MAPS` (root, lower spine, upper spine, neck,
#: head, right collar/shoulder/elbow/wrist, left collar/shoulder/elbow/wrist, right hip/knee/ankle, left
#: hip/knee/ankle): entry k plays the role of ``JOINT_MAPS[kind][k]``.
HSC_ROLE_ORDER = [
    "Hips",
    "Chest",
    "CS_BVH",
    "Neck",
    "Head",
    "RightCollar",
    "RightShoulder",
    "RightElbow",
    "RightWrist",
    "LeftCollar",
    "LeftShoulder",
    "LeftElbow",
    "LeftWrist",
    "RightHip",
    "RightKnee",
    "RightAnkle",
    "LeftHip",
    "LeftKnee",
    "LeftAnkle",
]
_AXIS = {"Xrotation": 0, "Yrotation": 1, "Zrotation": 2}
_ORDER = [_AXIS[c] for c in HSC_CHANNELS]


def hsc_skeleton():
    """The authors' 19-joint skeleton (``hierarchy2.bvh``) as a :class:`bsrbench.mocap.Skeleton` (24 joints with
    the 5 end sites; the root has 6 channels, the others ``Zrotation Xrotation Yrotation``; length unit: the
    file's, a standing figure is about 65 units tall)."""
    names = [n for n, _, _ in _HIERARCHY]
    parents = [-1 if p is None else names.index(p) for _, p, _ in _HIERARCHY]
    channels = []
    for n, p, _ in _HIERARCHY:
        if n.endswith("_End"):
            channels.append(())
        elif p is None:
            channels.append(("Xposition", "Yposition", "Zposition") + HSC_CHANNELS)
        else:
            channels.append(HSC_CHANNELS)
    return Skeleton(
        names, parents, [o for _, _, o in _HIERARCHY], channels, [n.endswith("_End") for n in names]
    )


def _pose_angles(Y, what="hsc pose"):
    """(F, 57) float array from a row (57,), rows (F, 57) or rows with the root translation first (F, 60)."""
    Y = np.atleast_2d(np.asarray(Y, dtype=float))
    if Y.ndim != 2 or Y.shape[1] not in (57, 60):
        raise InputError(
            f"{what}: expected rows of 57 angles (or 60 with the root translation); got {Y.shape}"
        )
    Y = Y[:, -57:]
    if not np.all(np.isfinite(Y)):
        raise InputError(f"{what}: has non-finite angles")
    return Y


def hsc_rotations(Y):
    """Local rotation matrices (F, 19, 3, 3) of the 19 joints from rows of 57 (or 60) angles in degrees."""
    Y = _pose_angles(Y)
    F = Y.shape[0]
    R = np.empty((F, 19, 3, 3))
    for j in range(19):
        R[:, j] = euler_matrix(_ORDER, Y[:, 3 * j : 3 * j + 3])
    return R


def hsc_positions(Y, centred=True):
    """3-D joint positions (F, 24, 3) of the authors' skeleton posed by rows ``Y`` of 57 angles in degrees (or
    60 columns, the root translation first, which is then applied unless ``centred``).

    Forward kinematics on :func:`hsc_skeleton` (BVH convention, y up). ``centred``: root at the origin. The
    joints are those of ``hsc_skeleton().joint_names``, parents ``hsc_skeleton().parents``. A single row (57,)
    gives (1, 24, 3). Raises InputError for another shape or non-finite angles.
    """
    Yraw = np.atleast_2d(np.asarray(Y, dtype=float))
    Y = _pose_angles(Yraw)
    skel = hsc_skeleton()
    F, J = Y.shape[0], len(skel.joint_names)
    R = np.broadcast_to(np.eye(3), (F, J, 3, 3)).copy()
    rot = hsc_rotations(Y)
    for k, j in enumerate(HSC_JOINTS):
        R[:, skel.index(j)] = rot[:, k]
    T = np.broadcast_to(skel.offsets, (F, J, 3)).copy()
    if Yraw.shape[1] == 60 and not centred:
        T[:, 0] += Yraw[:, :3]
    return forward_kinematics(skel.parents, R, T)[0]


def hsc_stick_figure(angles):
    """One authors' pose as a 3-D stick figure: ``(positions (24, 3), parents (24,))``, root at the origin.

    ``angles``: the 57 pose angles of one row (degrees; e.g. a row of ``Y`` in a features file of the hsc source,
    a prediction, or a .mat row without its 3 translation columns). Joints and parents are those of
    :func:`hsc_skeleton` (y up, as the mocap stick figures). Raises InputError for another shape.
    """
    a = np.asarray(angles, dtype=float)
    if a.shape != (57,):
        raise InputError(
            f"hsc_stick_figure: expected the 57 angles of one pose; got shape {a.shape}"
        )
    return hsc_positions(a[None])[0], hsc_skeleton().parents.copy()


def canonical_euler(R):
    """Euler angles (..., 3) in degrees, in the authors' column order (Z, X, Y; ``R = Rz @ Rx @ Ry``), with the
    middle (X) angle in [-90, 90] -- the decomposition their files use (a knee bent past 90 degrees appears as
    Z = 180, X = 180 - bend, Y = 180)."""
    R = np.asarray(R, dtype=float)
    shape = R.shape[:-2]
    # scipy's intrinsic "ZXY" is R = Rz(a) Rx(b) Ry(c), with b in [-90, 90]
    e = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True)
    return e.reshape(shape + (3,))


# ---------------------------------------------------------------------------------------------- row alignment
def _window_fit(S, W):
    """Per-axis affine fit W ~ a*S + b over a window: slopes (3,), intercepts (3,), residual (L, 3)."""
    Sm, Wm = S.mean(0), W.mean(0)
    Sc, Wc = S - Sm, W - Wm
    var = (Sc**2).sum(0)
    a = np.where(var > 1e-12, (Sc * Wc).sum(0) / np.maximum(var, 1e-12), 0.0)
    b = Wm - a * Sm
    return a, b, W - (a * S + b)


def align_rows(T_rows, trials, stride=4, min_overlap=8):
    """Find, for each trial, the rows of an authors' file it fills.

    ``T_rows`` (R, 3): the root translation of every row (the first 3 columns of ``Y``). ``trials``: list of
    ``(trial_id, positions)`` with the root position (n, 3) of every frame of the 120 fps file (frame 0
    included). Each trial at every ``stride``-th frame, for each phase ``0 .. stride-1``, is slid over the rows
    (a window may run past the last row: the file may end inside a trial, at least ``min_overlap`` rows); per
    axis an affine map ``theirs = a * ours + b`` is fitted on the window and the window scored by its RMS
    residual divided by the RMS spread of the window (a scale-free number; 0 is a perfect fit).

    Returns a list of dicts, one per trial (best window): ``trial``, ``phase``, ``start_row``, ``n_rows``,
    ``slope`` (3,), ``intercept`` (3,), ``score`` and ``rms`` (3,) (residual per axis, their units).
    """
    T_rows = np.asarray(T_rows, dtype=float)
    if T_rows.ndim != 2 or T_rows.shape[1] != 3:
        raise InputError(f"align_rows: expected the root translation (rows, 3); got {T_rows.shape}")
    R = T_rows.shape[0]
    out = []
    for tid, P in trials:
        P = np.asarray(P, dtype=float)
        best = None
        for phase in range(stride):
            S_all = P[phase::stride]
            for r0 in range(0, R - min_overlap + 1):
                L = min(len(S_all), R - r0)
                if L < min_overlap:
                    continue
                S, W = S_all[:L], T_rows[r0 : r0 + L]
                a, b, res = _window_fit(S, W)
                spread = np.sqrt(((W - W.mean(0)) ** 2).sum(1).mean())
                score = np.sqrt((res**2).sum(1).mean()) / max(spread, 1e-9)
                if best is None or score < best["score"]:
                    best = {
                        "trial": tid,
                        "phase": phase,
                        "start_row": r0,
                        "n_rows": L,
                        "slope": a,
                        "intercept": b,
                        "score": float(score),
                        "rms": np.sqrt((res**2).mean(0)),
                    }
        out.append(best)
    return out


def align_rows_by_angles(Y_rows, trial_angles, stride=4, min_overlap=8):
    """Find the rows an authors' file fills with one trial, by the pose angles instead of the root trajectory.

    ``Y_rows`` (R, 57): their angles; ``trial_angles`` (n, 57): the trial's poses at every frame of its 120 fps
    file, already written in their convention (:func:`ours_to_hsc_angles`). Same sliding search as
    :func:`align_rows`; a window's score is the median absolute wrapped difference in degrees. Returns one
    dict like :func:`align_rows` (``slope``, ``intercept`` and ``rms`` are NaN).
    """
    Y_rows = _pose_angles(Y_rows, "align_rows_by_angles")
    P = np.asarray(trial_angles, dtype=float)
    R = Y_rows.shape[0]
    best = None
    for phase in range(stride):
        S_all = P[phase::stride]
        for r0 in range(0, R - min_overlap + 1):
            L = min(len(S_all), R - r0)
            if L < min_overlap:
                continue
            score = float(np.median(np.abs(wrapped_diff(Y_rows[r0 : r0 + L], S_all[:L]))))
            if best is None or score < best["score"]:
                best = {"phase": phase, "start_row": r0, "n_rows": L, "score": score}
    nan3 = np.full(3, np.nan)
    return {**best, "slope": nan3, "intercept": nan3, "rms": nan3}


def translation_residuals(T_rows, matches, trials, slope):
    """Per matched row, the root-translation residual with one common per-axis ``slope`` (3,) and a per-trial
    intercept (the least-squares one): dict trial -> (rows (L,), frames (L,), residual (L, 3) in their units)."""
    P = dict(trials)
    slope = np.asarray(slope, dtype=float)
    out = {}
    for m in matches:
        rows = np.arange(m["start_row"], m["start_row"] + m["n_rows"])
        frames = m["phase"] + 4 * np.arange(m["n_rows"])
        S = np.asarray(P[m["trial"]], dtype=float)[frames]
        W = np.asarray(T_rows, dtype=float)[rows]
        b = (W - slope * S).mean(0)
        out[m["trial"]] = (rows, frames, W - (slope * S + b))
    return out


# ------------------------------------------------------------------------------------------ angle convention
def _procrustes(M):
    """The rotation closest to ``M`` (3, 3) in the Frobenius norm (orthogonal Procrustes with det = +1)."""
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def geodesic_deg(Ra, Rb):
    """Rotation angle (degrees) of ``Ra^T Rb`` for stacks of rotation matrices (..., 3, 3)."""
    tr = np.einsum("...ij,...ij->...", Ra, Rb)
    return np.rad2deg(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


def fit_joint_rotations(R_theirs, R_ours, n_iter=50):
    """Constant rotations ``A``, ``B`` with ``R_theirs[f] ~ A @ R_ours[f] @ B`` for every frame ``f``.

    ``R_theirs``, ``R_ours``: (F, 3, 3) local rotations of one joint on aligned frames. Alternating orthogonal
    Procrustes (Schoenemann 1966) on the Frobenius loss, started from ``A = I``, ``B = mean rotation``. Returns
    ``(A, B, residual)`` with residual (F,) the geodesic angle in degrees between ``R_theirs`` and the fit.
    """
    Rt = np.asarray(R_theirs, dtype=float)
    Ro = np.asarray(R_ours, dtype=float)
    A = np.eye(3)
    B = _procrustes(np.einsum("fji,fjk->ik", Ro, Rt))  # B minimising sum |Rt - Ro B|
    prev = np.inf
    for _ in range(n_iter):
        A = _procrustes(np.einsum("fij,fkj->ik", Rt, Ro @ B))  # sum Rt (Ro B)^T
        B = _procrustes(np.einsum("fji,fjk->ik", A @ Ro, Rt))  # sum (A Ro)^T Rt
        loss = ((Rt - A @ Ro @ B) ** 2).sum()
        if prev - loss < 1e-10 * max(prev, 1.0):
            break
        prev = loss
    return A, B, geodesic_deg(Rt, A @ Ro @ B)


def ours_to_hsc_angles(R_ours_roles, A, B):
    """Our local rotations (F, 19, 3, 3), in role order, written as the authors' 57 angles (F, 57) in
    degrees: joint k of :data:`HSC_ROLE_ORDER` gets ``canonical_euler(A[k] @ R @ B[k])`` in its columns."""
    R = np.asarray(R_ours_roles, dtype=float)
    F = R.shape[0]
    out = np.empty((F, 57))
    for k, j in enumerate(HSC_ROLE_ORDER):
        c = HSC_JOINTS.index(j)
        out[:, 3 * c : 3 * c + 3] = canonical_euler(A[k] @ R[:, k] @ B[k])
    return out


def hsc_to_role_rotations(Y, A, B):
    """The inverse of :func:`ours_to_hsc_angles` up to the fit: our local rotations (F, 19, 3, 3) in role
    order, ``A[k]^T @ R_theirs @ B[k]^T``, from rows of the authors' 57 (or 60) angles."""
    R = hsc_rotations(Y)
    out = np.empty_like(R)
    for k, j in enumerate(HSC_ROLE_ORDER):
        out[:, k] = A[k].T @ R[:, HSC_JOINTS.index(j)] @ B[k].T
    return out


def save_angle_mapping(path, A, B, our_joints, skeleton_kind):
    """Write the per-joint rotations ``A``, ``B`` (19, 3, 3) of :func:`fit_joint_rotations` as a CSV: one line
    per joint in :data:`HSC_ROLE_ORDER` with our joint's name, the skeleton kind and both rotations as rotation
    vectors in radians (full precision)."""
    import pandas as pd

    from .io import atomic_path

    a = Rotation.from_matrix(np.asarray(A)).as_rotvec()
    b = Rotation.from_matrix(np.asarray(B)).as_rotvec()
    df = pd.DataFrame(
        {
            "hsc_joint": HSC_ROLE_ORDER,
            "our_joint": list(our_joints),
            "skeleton_kind": skeleton_kind,
            "A_x": a[:, 0],
            "A_y": a[:, 1],
            "A_z": a[:, 2],
            "B_x": b[:, 0],
            "B_y": b[:, 1],
            "B_z": b[:, 2],
        }
    )
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False, float_format="%.17g")


def load_angle_mapping(path):
    """Read a mapping written by :func:`save_angle_mapping`: ``(A, B, our_joints, skeleton_kind)`` with A, B
    (19, 3, 3) in :data:`HSC_ROLE_ORDER`. Raises DataFileError naming the file when a column or joint is
    missing or out of order."""
    import pandas as pd

    from .errors import DataFileError

    try:
        df = pd.read_csv(path)
    except (OSError, ValueError) as e:
        raise DataFileError(path, f"cannot be read as a CSV ({e})") from None
    need = ["hsc_joint", "our_joint", "skeleton_kind", "A_x", "A_y", "A_z", "B_x", "B_y", "B_z"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise DataFileError(path, f"has no column(s) {missing}; expected {need}")
    if list(df["hsc_joint"]) != HSC_ROLE_ORDER:
        raise DataFileError(
            path, f"hsc_joint must list {HSC_ROLE_ORDER} in that order; got {list(df['hsc_joint'])}"
        )
    A = Rotation.from_rotvec(df[["A_x", "A_y", "A_z"]].to_numpy(float)).as_matrix()
    B = Rotation.from_rotvec(df[["B_x", "B_y", "B_z"]].to_numpy(float)).as_matrix()
    return A, B, [str(j) for j in df["our_joint"]], str(df["skeleton_kind"].iloc[0])


def wrapped_diff(a, b):
    """``a - b`` in degrees wrapped to (-180, 180]."""
    d = wrap_degrees(np.asarray(a, dtype=float) - np.asarray(b, dtype=float))
    return np.where(d == -180.0, 180.0, d)


def column_correlations(Y_theirs, Y_ours, ours_names):
    """For every column of ``Y_theirs`` (F, 57) the column of ``Y_ours`` (F, 57) with the largest absolute
    Pearson correlation, and the least-squares line ``theirs ~ slope * ours + offset`` on it.

    Both are unwrapped over the frames first (their knees and elbows flip between Euler branches, which no
    line follows; the row of such a column shows a low correlation). Constant columns get correlation 0.
    Returns a list of dicts: ``hsc_column``, ``ours_column``, ``corr``, ``slope``, ``offset``, ``rms`` (deg).
    """
    Yt = np.unwrap(np.asarray(Y_theirs, dtype=float), period=360.0, axis=0)
    Yo = np.unwrap(np.asarray(Y_ours, dtype=float), period=360.0, axis=0)
    zt = Yt - Yt.mean(0)
    zo = Yo - Yo.mean(0)
    st, so = np.sqrt((zt**2).sum(0)), np.sqrt((zo**2).sum(0))
    C = (zt.T @ zo) / np.maximum(np.outer(st, so), 1e-12)
    C[st < 1e-9] = 0.0
    C[:, so < 1e-9] = 0.0
    rows = []
    for i, name in enumerate(HSC_ANGLE_NAMES):
        k = int(np.argmax(np.abs(C[i])))
        if C[i, k] == 0.0:
            rows.append(
                {
                    "hsc_column": name,
                    "ours_column": "",
                    "corr": 0.0,
                    "slope": 0.0,
                    "offset": float(Yt[:, i].mean()),
                    "rms": float(Yt[:, i].std()),
                }
            )
            continue
        slope = (zt[:, i] @ zo[:, k]) / (so[k] ** 2)
        offset = Yt[:, i].mean() - slope * Yo[:, k].mean()
        rms = np.sqrt(np.mean((Yt[:, i] - slope * Yo[:, k] - offset) ** 2))
        rows.append(
            {
                "hsc_column": name,
                "ours_column": ours_names[k],
                "corr": float(C[i, k]),
                "slope": float(slope),
                "offset": float(offset),
                "rms": float(rms),
            }
        )
    return rows
