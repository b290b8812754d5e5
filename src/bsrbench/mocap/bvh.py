"""Biovision Hierarchy (BVH) reader and writer.

Format: Meredith & Maddock, "Motion capture file formats explained" (University of Sheffield, 2001).
Any hierarchy and any channel order are accepted: channel names and order are read from each joint's
``CHANNELS`` line, never assumed. End sites become joints named ``<parent>_End`` with no channels.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ..io import atomic_path
from .skeleton import CHANNEL_NAMES, Skeleton, skeleton_positions


@dataclass
class BVHData:
    """A parsed BVH file: ``skeleton``, ``motion`` (F, C) channel values, ``frame_time`` (s), ``path``."""

    skeleton: Skeleton
    motion: np.ndarray
    frame_time: float
    path: str = ""

    @property
    def n_frames(self):
        return self.motion.shape[0]

    def positions(self):
        """World joint positions (F, J, 3) by forward kinematics."""
        return skeleton_positions(self.skeleton, self.motion)


def _number(path, lineno, token, what):
    try:
        return float(token)
    except ValueError:
        raise DataFileError(path, f"line {lineno}: {what}: {token!r} is not a number") from None


def parse_bvh(path):
    """Read a BVH file into a :class:`BVHData`.

    Raises :class:`~bsrbench.errors.DataFileError` naming the file and line when the file is missing, the
    hierarchy is malformed, a channel name is unknown, a motion row has the wrong number of values or a
    non-number, or there are fewer (or more) motion rows than ``Frames:`` declares.
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "file not found (expected a BVH motion file)")
    with open(path, encoding="utf-8", errors="replace") as fh:
        lines = fh.read().splitlines()

    names, parents, offsets, channels, end_site = [], [], [], [], []
    stack = []  # indices of open joints
    pending = None  # joint created but whose "{" is not yet seen
    i = 0
    n = len(lines)

    def toks(k):
        return lines[k].split()

    # skip to HIERARCHY
    while i < n and not lines[i].strip():
        i += 1
    if i >= n or toks(i)[0].upper() != "HIERARCHY":
        raise DataFileError(path, f"line {i + 1}: expected 'HIERARCHY' at the start of a BVH file")
    i += 1
    motion_line = None
    while i < n:
        t = toks(i)
        lineno = i + 1
        if not t:
            i += 1
            continue
        key = t[0].upper()
        if key in ("ROOT", "JOINT") or (key == "END" and len(t) > 1 and t[1].upper() == "SITE"):
            if key == "ROOT" and (names or stack):
                raise DataFileError(path, f"line {lineno}: a second ROOT is not supported")
            if key != "ROOT" and not stack:
                raise DataFileError(path, f"line {lineno}: {t[0]} outside of a joint's braces")
            parent = stack[-1] if stack else -1
            if key == "END":
                base = f"{names[parent]}_End"
                name, k = base, 1
                while name in names:
                    k += 1
                    name = f"{base}{k}"
                is_end = True
            else:
                if len(t) < 2:
                    raise DataFileError(path, f"line {lineno}: {t[0]} needs a joint name")
                name = " ".join(t[1:])
                if name in names:
                    raise DataFileError(path, f"line {lineno}: joint name {name!r} appears twice")
                is_end = False
            names.append(name)
            parents.append(parent)
            offsets.append(None)
            channels.append(())
            end_site.append(is_end)
            pending = len(names) - 1
        elif key == "{":
            if pending is None:
                raise DataFileError(path, f"line {lineno}: '{{' without a ROOT/JOINT/End Site before it")
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack:
                raise DataFileError(path, f"line {lineno}: unmatched '}}'")
            j = stack.pop()
            if offsets[j] is None:
                raise DataFileError(path, f"line {lineno}: joint {names[j]!r} has no OFFSET")
        elif key == "OFFSET":
            if not stack:
                raise DataFileError(path, f"line {lineno}: OFFSET outside of a joint")
            if len(t) != 4:
                raise DataFileError(path, f"line {lineno}: OFFSET needs 3 numbers, found {len(t) - 1}")
            offsets[stack[-1]] = [_number(path, lineno, x, "OFFSET") for x in t[1:]]
        elif key == "CHANNELS":
            if not stack:
                raise DataFileError(path, f"line {lineno}: CHANNELS outside of a joint")
            j = stack[-1]
            if end_site[j]:
                raise DataFileError(path, f"line {lineno}: an End Site cannot have CHANNELS")
            if len(t) < 2:
                raise DataFileError(path, f"line {lineno}: CHANNELS needs a count")
            try:
                count = int(t[1])
            except ValueError:
                raise DataFileError(path, f"line {lineno}: CHANNELS count {t[1]!r} is not an integer") from None
            chans = tuple(t[2:])
            if len(chans) != count:
                raise DataFileError(path, f"line {lineno}: CHANNELS declares {count} channels but names {len(chans)}")
            for c in chans:
                if c not in CHANNEL_NAMES:
                    raise DataFileError(
                        path, f"line {lineno}: unknown channel {c!r}; expected one of {', '.join(CHANNEL_NAMES)}"
                    )
            if len(set(chans)) != len(chans):
                raise DataFileError(path, f"line {lineno}: joint {names[j]!r} repeats a channel: {chans}")
            channels[j] = chans
        elif key == "MOTION":
            if stack or pending is not None:
                raise DataFileError(path, f"line {lineno}: MOTION before every joint's braces are closed")
            motion_line = i
            break
        else:
            raise DataFileError(path, f"line {lineno}: unexpected token {t[0]!r} in HIERARCHY")
        i += 1
    if not names:
        raise DataFileError(path, "no ROOT joint in HIERARCHY")
    if motion_line is None:
        raise DataFileError(path, f"line {n}: file ends before the MOTION section")

    # MOTION header
    i = motion_line + 1
    header = {}
    for label in ("frames", "frame time"):
        while i < n and not lines[i].strip():
            i += 1
        if i >= n:
            raise DataFileError(path, f"line {n}: file ends before the '{label.title()}:' line of MOTION")
        head, sep, value = lines[i].partition(":")
        if not sep or head.strip().lower() != label:
            raise DataFileError(path, f"line {i + 1}: expected '{label.title()}: <value>', found {lines[i].strip()!r}")
        header[label] = (value.strip(), i + 1)
        i += 1
    frames_txt, frames_line = header["frames"]
    try:
        n_frames = int(frames_txt)
    except ValueError:
        raise DataFileError(path, f"line {frames_line}: Frames: {frames_txt!r} is not an integer") from None
    if n_frames < 1:
        raise DataFileError(path, f"line {frames_line}: Frames: must be >= 1, found {n_frames}")
    ft_txt, ft_line = header["frame time"]
    frame_time = _number(path, ft_line, ft_txt, "Frame Time")
    if not frame_time > 0:
        raise DataFileError(path, f"line {ft_line}: Frame Time must be > 0, found {frame_time}")

    skeleton = Skeleton(names, parents, [o for o in offsets], list(channels), end_site)
    n_ch = skeleton.n_channels
    motion = np.empty((n_frames, n_ch))
    row = 0
    for k in range(i, n):
        t = lines[k].split()
        if not t:
            continue
        if row >= n_frames:
            raise DataFileError(path, f"line {k + 1}: more motion rows than 'Frames: {n_frames}' (line {frames_line})")
        if len(t) != n_ch:
            raise DataFileError(
                path, f"line {k + 1}: motion row {row} has {len(t)} values; expected {n_ch} (one per declared channel)"
            )
        try:
            motion[row] = np.array(t, dtype=float)
        except ValueError:
            bad = next(c for c, x in enumerate(t) if not _isfloat(x))
            raise DataFileError(
                path, f"line {k + 1}, value {bad + 1}: {t[bad]!r} is not a number (motion row {row})"
            ) from None
        row += 1
    if row < n_frames:
        raise DataFileError(
            path, f"file is truncated: 'Frames: {n_frames}' (line {frames_line}) but only {row} motion rows follow"
        )
    if not np.all(np.isfinite(motion)):
        r, c = np.argwhere(~np.isfinite(motion))[0]
        raise DataFileError(path, f"motion row {r}, value {c + 1} is not finite ({motion[r, c]})")
    return BVHData(skeleton, motion, frame_time, str(path))


def _isfloat(x):
    try:
        float(x)
        return True
    except ValueError:
        return False


def format_bvh(skeleton, motion, frame_time):
    """BVH text for ``skeleton`` with channel values ``motion`` (F, C)."""
    motion = np.asarray(motion, dtype=float)
    if motion.ndim != 2 or motion.shape[1] != skeleton.n_channels:
        raise DataFileError("<bvh>", f"motion must be (frames, {skeleton.n_channels}); got {motion.shape}")
    children = [[] for _ in skeleton.joint_names]
    for j, p in enumerate(skeleton.parents):
        if p >= 0:
            children[p].append(j)
    out = ["HIERARCHY"]

    def emit(j, depth):
        ind = "  " * depth
        if skeleton.end_site[j]:
            out.append(f"{ind}End Site")
        else:
            out.append(f"{ind}{'ROOT' if skeleton.parents[j] < 0 else 'JOINT'} {skeleton.joint_names[j]}")
        out.append(f"{ind}{{")
        out.append(f"{ind}  OFFSET " + " ".join(repr(float(v)) for v in skeleton.offsets[j]))
        if not skeleton.end_site[j]:
            ch = skeleton.channels[j]
            out.append(f"{ind}  CHANNELS {len(ch)} " + " ".join(ch))
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{ind}}}")

    emit(0, 0)
    out += ["MOTION", f"Frames: {motion.shape[0]}", f"Frame Time: {frame_time!r}"]
    out += [" ".join(repr(float(v)) for v in row) for row in motion]
    return "\n".join(out) + "\n"


def write_bvh(path, skeleton, motion, frame_time):
    """Write a BVH file atomically (full float precision, so :func:`parse_bvh` reads back the same values)."""
    text = format_bvh(skeleton, motion, frame_time)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
