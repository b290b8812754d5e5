"""Biovision Hierarchy (BVH) reader and writer.

Format: Meredith & Maddock, "Motion capture file formats explained" (University of Sheffield, 2001).
Any hierarchy and any channel order are accepted: channel names and order are read from each joint's
``CHANNELS`` line, never assumed. Text handling (BOM, line ends, tokens, numbers) is in :mod:`._text`. End sites become joints named ``<parent>_End`` with no channels.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ..io import atomic_path
from ._text import first_bad_number, is_number, is_whole, read_lines
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


def _fail(path, lineno, message):
    return DataFileError(path, f"line {lineno}: {message}", line=lineno)


def _number(path, lineno, token, what):
    if not is_number(token):
        raise _fail(path, lineno, f"{what}: {token!r} is not a number")
    return float(token)


#: Channel names in any letter case -> the canonical name.
_CHANNELS = {c.lower(): c for c in CHANNEL_NAMES}


def parse_bvh(path):
    """Read a BVH file into a :class:`BVHData`.

    Accepts what Biovision files are written with: a UTF-8 byte-order mark, LF/CRLF/CR line ends, tabs or
    spaces, keywords and channel names in any letter case (``End Site``, ``END SITE``; ``Xrotation``,
    ``XROTATION``), ``Frames:``/``Frame Time:`` with any spacing.
    Raises :class:`~bsrbench.errors.DataFileError` (an InputError) naming the file and line (``.line``) when the
    file is missing, the hierarchy is malformed, a channel name is unknown, a motion row has the wrong number of
    values or a non-number, or there are fewer (or more) motion rows than ``Frames:`` declares.
    """
    path = Path(path)
    lines = read_lines(path, "a BVH motion file")

    names, parents, offsets, channels, end_site, opened = [], [], [], [], [], []
    stack = []  # indices of open joints
    pending = None  # joint created but whose "{" is not yet seen
    i = 0
    n = len(lines)

    def toks(k):
        return lines[k].split()

    while i < n and not lines[i].strip():
        i += 1
    if i >= n or toks(i)[0].upper() != "HIERARCHY" or len(toks(i)) != 1:
        found = repr(lines[i].strip()[:40]) if i < n else "the end of the file"
        raise _fail(
            path,
            min(i + 1, max(n, 1)),
            f"expected 'HIERARCHY' at the start of a BVH file, found {found}",
        )
    i += 1
    motion_line = None
    while i < n:
        t = toks(i)
        lineno = i + 1
        if not t:
            i += 1
            continue
        key = t[0].upper()
        if pending is not None and key != "{":
            raise _fail(
                path, lineno, f"expected '{{' after joint {names[pending]!r}, found {t[0][:40]!r}"
            )
        if key in ("ROOT", "JOINT") or (key == "END" and len(t) == 2 and t[1].upper() == "SITE"):
            if key == "ROOT" and (names or stack):
                raise _fail(path, lineno, "a second ROOT is not supported")
            if key != "ROOT" and not stack:
                raise _fail(path, lineno, f"{t[0]} outside of a joint's braces")
            parent = stack[-1] if stack else -1
            if parent >= 0 and end_site[parent]:
                raise _fail(path, lineno, f"an End Site cannot have children; found {t[0]!r}")
            if key == "END":
                base = f"{names[parent]}_End"
                name, k = base, 1
                while name in names:
                    k += 1
                    name = f"{base}{k}"
                is_end = True
            else:
                if len(t) < 2:
                    raise _fail(path, lineno, f"{t[0]} needs a joint name")
                name = " ".join(t[1:])
                if name in names:
                    raise _fail(path, lineno, f"joint name {name!r} appears twice")
                is_end = False
            names.append(name)
            parents.append(parent)
            offsets.append(None)
            channels.append(())
            end_site.append(is_end)
            opened.append(lineno)
            pending = len(names) - 1
        elif key == "{":
            if pending is None or len(t) != 1:
                raise _fail(
                    path,
                    lineno,
                    "expected '{' alone on its line after a ROOT, JOINT or End Site line",
                )
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack or len(t) != 1:
                raise _fail(
                    path, lineno, "unmatched '}'" if not stack else "expected '}' alone on its line"
                )
            j = stack.pop()
            if offsets[j] is None:
                raise _fail(path, lineno, f"joint {names[j]!r} has no OFFSET")
        elif key == "OFFSET":
            if not stack:
                raise _fail(path, lineno, "OFFSET outside of a joint's braces")
            if len(t) != 4:
                raise _fail(path, lineno, f"OFFSET needs 3 numbers, found {len(t) - 1}")
            if offsets[stack[-1]] is not None:
                raise _fail(path, lineno, f"joint {names[stack[-1]]!r} has a second OFFSET")
            offsets[stack[-1]] = [_number(path, lineno, x, "OFFSET") for x in t[1:]]
        elif key == "CHANNELS":
            if not stack:
                raise _fail(path, lineno, "CHANNELS outside of a joint's braces")
            j = stack[-1]
            if end_site[j]:
                raise _fail(path, lineno, "an End Site cannot have CHANNELS")
            if channels[j]:
                raise _fail(path, lineno, f"joint {names[j]!r} has a second CHANNELS line")
            if len(t) < 2 or not is_whole(t[1]):
                raise _fail(
                    path,
                    lineno,
                    f"CHANNELS needs a count, found {t[1] if len(t) > 1 else 'nothing'!r}",
                )
            count = int(t[1])
            chans = t[2:]
            if len(chans) != count:
                raise _fail(
                    path, lineno, f"CHANNELS declares {count} channels but names {len(chans)}"
                )
            for c in chans:
                if c.lower() not in _CHANNELS:
                    raise _fail(
                        path,
                        lineno,
                        f"unknown channel {c!r}; expected one of {', '.join(CHANNEL_NAMES)}",
                    )
            chans = tuple(_CHANNELS[c.lower()] for c in chans)
            if len(set(chans)) != len(chans):
                raise _fail(path, lineno, f"joint {names[j]!r} repeats a channel: {chans}")
            channels[j] = chans
        elif key == "MOTION":
            if len(t) != 1:
                raise _fail(
                    path,
                    lineno,
                    f"expected 'MOTION' alone on its line, found {lines[i].strip()[:40]!r}",
                )
            if stack:
                open_ = stack[-1]
                raise _fail(
                    path,
                    lineno,
                    f"MOTION before the braces of joint {names[open_]!r} (line {opened[open_]}) close",
                )
            motion_line = i
            break
        elif key == "HIERARCHY":
            raise _fail(path, lineno, "a second HIERARCHY line")
        else:
            raise _fail(
                path,
                lineno,
                f"unexpected {t[0][:40]!r} in HIERARCHY; expected ROOT, JOINT, End Site, '{{', '}}', "
                "OFFSET, CHANNELS or MOTION",
            )
        i += 1
    if motion_line is None:
        raise _fail(path, max(n, 1), "file ends before the MOTION section")
    if not names:
        raise _fail(path, motion_line + 1, "no ROOT joint before MOTION")

    # MOTION header
    i = motion_line + 1
    header = {}
    for label in ("frames", "frame time"):
        while i < n and not lines[i].strip():
            i += 1
        if i >= n:
            raise _fail(path, max(n, 1), f"file ends before the '{label.title()}:' line of MOTION")
        head, sep, value = lines[i].partition(":")
        if not sep or " ".join(head.split()).lower() != label:
            raise _fail(
                path, i + 1, f"expected '{label.title()}: <value>', found {lines[i].strip()[:40]!r}"
            )
        header[label] = (value.strip(), i + 1)
        i += 1
    frames_txt, frames_line = header["frames"]
    if not is_whole(frames_txt):
        raise _fail(path, frames_line, f"Frames: {frames_txt[:40]!r} is not a whole number")
    n_frames = int(frames_txt)
    if n_frames < 1:
        raise _fail(path, frames_line, f"Frames: must be >= 1, found {n_frames}")
    ft_txt, ft_line = header["frame time"]
    frame_time = _number(path, ft_line, ft_txt, "Frame Time")
    if not frame_time > 0:
        raise _fail(path, ft_line, f"Frame Time must be > 0, found {frame_time}")

    skeleton = Skeleton(names, parents, [o for o in offsets], list(channels), end_site)
    n_ch = skeleton.n_channels
    if n_ch == 0:
        raise _fail(
            path, motion_line + 1, "no joint declares CHANNELS; expected at least one channel"
        )
    rows = []
    for k in range(i, n):
        t = lines[k].split()
        if not t:
            continue
        if len(rows) >= n_frames:
            raise _fail(
                path, k + 1, f"more motion rows than 'Frames: {n_frames}' (line {frames_line})"
            )
        if len(t) != n_ch:
            raise _fail(
                path,
                k + 1,
                f"motion row {len(rows)} has {len(t)} values; expected {n_ch} (one per declared channel)",
            )
        bad = first_bad_number(t)
        if bad is not None:
            raise DataFileError(
                path,
                f"line {k + 1}, value {bad + 1}: {t[bad][:40]!r} is not a number (motion row {len(rows)})",
                line=k + 1,
            )
        rows.append(t)
    if len(rows) < n_frames:
        raise _fail(
            path,
            max(n, 1),
            f"file is truncated: 'Frames: {n_frames}' (line {frames_line}) but only {len(rows)} motion rows follow",
        )
    motion = np.array(rows, dtype=float)
    return BVHData(skeleton, motion, frame_time, str(path))


def format_bvh(skeleton, motion, frame_time):
    """BVH text for ``skeleton`` with channel values ``motion`` (F, C)."""
    motion = np.asarray(motion, dtype=float)
    if motion.ndim != 2 or motion.shape[1] != skeleton.n_channels:
        raise DataFileError(
            "<bvh>", f"motion must be (frames, {skeleton.n_channels}); got {motion.shape}"
        )
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
            out.append(
                f"{ind}{'ROOT' if skeleton.parents[j] < 0 else 'JOINT'} {skeleton.joint_names[j]}"
            )
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
