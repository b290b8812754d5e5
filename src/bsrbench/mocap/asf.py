"""Acclaim ASF (skeleton) and AMC (motion) reader, as published by the CMU Graphics Lab Motion Capture Database.

Format: Acclaim Skeleton File definition v1.10 (Acclaim / Oxford Metrics; summarised in Lander, "Working with
Motion Capture File Formats", Game Developer, Jan. 1998, and in CMU's mocap.cs.cmu.edu documentation).

* ``:units`` gives ``length`` (a scale factor, kept as information; positions stay in the file's units) and
  ``angle`` (``deg`` or ``rad``; AMC ``:DEGREES``/``:RADIANS`` overrides it for the motion values).
* ``:root`` has ``order`` (the AMC channel order, e.g. ``TX TY TZ RX RY RZ``), ``axis`` (rotation order of
  ``orientation``), ``position`` and ``orientation``.
* Each bone has ``direction`` (unit vector in the world frame of the default pose), ``length``,
  ``axis ax ay az ORDER`` (the bone's local frame C), optional ``dof`` (subset of rx ry rz tx ty tz l, in
  the AMC value order) and ``limits`` (one interval per dof; read and kept, not enforced).

Kinematics (the usual ASF/AMC rule): the bone's world rotation is ``G_b = G_parent C_b M_b C_b^-1`` with
``M_b`` the motion rotation built from the dof values, rotations applied in the listed order (``rx ry rz``
gives ``M = Rz Ry Rx``); the bone's end is its start plus ``G_b (length_b direction_b)``.
So every bone becomes a joint at its start with offset ``length_p direction_p`` from its parent bone and local
rotation ``C M C^-1``, and the ordinary tree forward kinematics of :mod:`.skeleton` applies. A BVH whose joints
use ``Zrotation Yrotation Xrotation`` and these offsets gives the same world positions when every axis is zero.
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from .skeleton import Skeleton, axis_rotation, forward_kinematics

_DOF_CHANNEL = {
    "rx": "Xrotation", "ry": "Yrotation", "rz": "Zrotation",
    "tx": "Xposition", "ty": "Yposition", "tz": "Zposition",
}
_AXIS = {"X": 0, "Y": 1, "Z": 2}


def _order_matrix(order, angles_deg):
    """Rotation applying ``order`` (e.g. "XYZ": x first) with angles (F, k): ``R_last @ ... @ R_first``."""
    angles_deg = np.asarray(angles_deg, dtype=float)
    R = np.broadcast_to(np.eye(3), (angles_deg.shape[0], 3, 3)).copy()
    for k, ax in enumerate(order):
        R = axis_rotation(_AXIS[ax], angles_deg[:, k]) @ R
    return R


@dataclass
class ASFSkeleton:
    """A parsed ASF file.

    ``skeleton`` is the joint tree (root + one joint per bone at the bone's start + an end site per leaf bone);
    ``skeleton.channels`` lists each joint's AMC values in file order, as BVH channel names (rx -> Xrotation).
    ``axes`` (J, 3, 3): each joint's frame C; ``limits``: bone name -> list of (lo, hi) per dof.
    """

    skeleton: Skeleton
    axes: np.ndarray
    root_order: tuple
    length_unit: float
    angle_unit: str
    limits: dict = field(default_factory=dict)
    path: str = ""


def _floats(path, lineno, tokens, n, what):
    if len(tokens) != n:
        raise DataFileError(path, f"line {lineno}: {what} needs {n} numbers, found {len(tokens)}")
    try:
        return [float(x) for x in tokens]
    except ValueError:
        bad = next(x for x in tokens if not _isfloat(x))
        raise DataFileError(path, f"line {lineno}: {what}: {bad!r} is not a number") from None


def _isfloat(x):
    try:
        float(x)
        return True
    except ValueError:
        return False


def parse_asf(path):
    """Read an ASF skeleton file into an :class:`ASFSkeleton` (errors name the file and line)."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "file not found (expected an ASF skeleton file)")
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    section = None
    units = {"length": 1.0, "angle": "deg"}
    root = {"order": None, "axis": "XYZ", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0]}
    bones = {}
    bone = None
    hierarchy = []
    in_limits = False
    for k, raw in enumerate(lines):
        lineno = k + 1
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        t = line.split()
        if t[0].startswith(":"):
            section = t[0][1:].lower()
            in_limits = False
            if bone is not None:
                raise DataFileError(path, f"line {lineno}: bone {bone.get('name')!r} has no 'end'")
            continue
        if section == "units":
            if t[0] == "length":
                units["length"] = _floats(path, lineno, t[1:], 1, "length")[0]
            elif t[0] == "angle":
                if len(t) != 2 or t[1].lower() not in ("deg", "rad"):
                    raise DataFileError(path, f"line {lineno}: angle unit must be 'deg' or 'rad', found {t[1:]}")
                units["angle"] = t[1].lower()
        elif section == "root":
            if t[0] == "order":
                order = tuple(x.upper() for x in t[1:])
                bad = [x for x in order if x.lower() not in _DOF_CHANNEL]
                if bad:
                    raise DataFileError(path, f"line {lineno}: root order has {bad}; expected TX TY TZ RX RY RZ")
                root["order"] = order
            elif t[0] == "axis":
                if len(t) != 2 or sorted(t[1].upper()) != ["X", "Y", "Z"]:
                    raise DataFileError(path, f"line {lineno}: root axis must be a permutation of XYZ, found {t[1:]}")
                root["axis"] = t[1].upper()
            elif t[0] in ("position", "orientation"):
                root[t[0]] = _floats(path, lineno, t[1:], 3, t[0])
        elif section == "bonedata":
            if t[0] == "begin":
                bone = {"dof": (), "limits": [], "axis": [0.0, 0.0, 0.0], "axis_order": "XYZ", "line": lineno}
                in_limits = False
            elif t[0] == "end":
                if bone is None:
                    raise DataFileError(path, f"line {lineno}: 'end' without 'begin'")
                for key in ("name", "direction", "length"):
                    if key not in bone:
                        raise DataFileError(path, f"line {bone['line']}: bone has no {key!r}")
                if bone["limits"] and len(bone["limits"]) != len(bone["dof"]):
                    raise DataFileError(
                        path,
                        f"line {lineno}: bone {bone['name']!r} has {len(bone['limits'])} limits for "
                        f"{len(bone['dof'])} dof",
                    )
                bones[bone["name"]] = bone
                bone = None
            elif bone is None:
                raise DataFileError(path, f"line {lineno}: {t[0]!r} outside a bone's begin/end")
            elif t[0] == "id":
                pass
            elif t[0] == "name":
                bone["name"] = t[1]
                in_limits = False
            elif t[0] == "direction":
                d = np.array(_floats(path, lineno, t[1:], 3, "direction"))
                nrm = np.linalg.norm(d)
                bone["direction"] = d / nrm if nrm > 0 else d
            elif t[0] == "length":
                bone["length"] = _floats(path, lineno, t[1:], 1, "length")[0]
            elif t[0] == "axis":
                if len(t) != 5 or sorted(t[4].upper()) != ["X", "Y", "Z"]:
                    raise DataFileError(path, f"line {lineno}: bone axis must be 'axis ax ay az XYZ', found {t[1:]}")
                bone["axis"] = _floats(path, lineno, t[1:4], 3, "axis")
                bone["axis_order"] = t[4].upper()
            elif t[0] == "dof":
                dof = tuple(x.lower() for x in t[1:])
                bad = [x for x in dof if x not in _DOF_CHANNEL]
                if bad:
                    raise DataFileError(path, f"line {lineno}: dof {bad} not supported; expected rx ry rz tx ty tz")
                bone["dof"] = dof
            elif t[0] == "limits" or in_limits:
                in_limits = True
                body = line[len("limits"):] if t[0] == "limits" else line
                body = body.replace("(", " ").replace(")", " ").split()
                lo_hi = []
                for x in body:
                    if x.lower() in ("inf", "+inf", "-inf"):
                        lo_hi.append(float(x.lower()))
                    else:
                        lo_hi += _floats(path, lineno, [x], 1, "limits")
                if len(lo_hi) != 2:
                    raise DataFileError(path, f"line {lineno}: a limit needs '(lo hi)', found {line!r}")
                bone["limits"].append(tuple(lo_hi))
            else:
                raise DataFileError(path, f"line {lineno}: unknown bone field {t[0]!r}")
        elif section == "hierarchy":
            if t[0] in ("begin", "end"):
                continue
            hierarchy.append((lineno, t[0], t[1:]))
    if root["order"] is None:
        raise DataFileError(path, "no ':root' section with an 'order' line")
    if not bones:
        raise DataFileError(path, "no bones in ':bonedata'")

    parent_of = {}
    children = {"root": []}
    for lineno, p, kids in hierarchy:
        if p != "root" and p not in bones:
            raise DataFileError(path, f"line {lineno}: hierarchy names unknown bone {p!r}")
        for c in kids:
            if c not in bones:
                raise DataFileError(path, f"line {lineno}: hierarchy names unknown bone {c!r}")
            if c in parent_of:
                raise DataFileError(path, f"line {lineno}: bone {c!r} has two parents")
            parent_of[c] = p
            children.setdefault(p, []).append(c)
    missing = [b for b in bones if b not in parent_of]
    if missing:
        raise DataFileError(path, f"bones not placed in ':hierarchy': {missing}")

    angle_scale = 1.0 if units["angle"] == "deg" else 180.0 / np.pi
    names = ["root"]
    parents = [-1]
    offsets = [np.array(root["position"], dtype=float)]
    channels = [tuple(_DOF_CHANNEL[x.lower()] for x in root["order"])]
    axes = [_order_matrix(root["axis"], np.array([root["orientation"]]) * angle_scale)[0]]
    end_site = [False]
    limits = {}

    def visit(name, parent_index):
        b = bones[name]
        names.append(name)
        parents.append(parent_index)
        pb = names[parent_index]
        offsets.append(np.zeros(3) if pb == "root" else bones[pb]["length"] * bones[pb]["direction"])
        channels.append(tuple(_DOF_CHANNEL[x] for x in b["dof"]))
        axes.append(_order_matrix(b["axis_order"], np.array([b["axis"]]) * angle_scale)[0])
        end_site.append(False)
        limits[name] = list(b["limits"])
        me = len(names) - 1
        kids = children.get(name, [])
        for c in kids:
            visit(c, me)
        if not kids:
            names.append(f"{name}_End")
            parents.append(me)
            offsets.append(b["length"] * b["direction"])
            channels.append(())
            axes.append(np.eye(3))
            end_site.append(True)

    for c in children["root"]:
        visit(c, 0)
    skel = Skeleton(names, parents, offsets, channels, end_site)
    return ASFSkeleton(
        skel, np.array(axes), root["order"], units["length"], units["angle"], limits, str(path)
    )


@dataclass
class AMCData:
    """A parsed AMC motion: ``asf`` (its skeleton), ``motion`` (F, C) values in degrees laid out as
    ``asf.skeleton.channels``, ``frame_time`` (s; AMC files carry none, CMU's rate is 120 Hz), ``path``."""

    asf: ASFSkeleton
    motion: np.ndarray
    frame_time: float
    path: str = ""

    @property
    def skeleton(self):
        return self.asf.skeleton

    @property
    def n_frames(self):
        return self.motion.shape[0]

    def positions(self):
        """World joint positions (F, J, 3) by forward kinematics (see the module docstring)."""
        return asf_positions(self.asf, self.motion)


def parse_amc(path, asf, frame_time=1.0 / 120.0):
    """Read an AMC motion file for the skeleton ``asf`` (an :class:`ASFSkeleton` or a path to an ASF file).

    Every frame must give every bone that has dof, with exactly that many values. Errors name the file and line.
    """
    if not isinstance(asf, ASFSkeleton):
        asf = parse_asf(asf)
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "file not found (expected an AMC motion file)")
    skel = asf.skeleton
    starts = skel.channel_starts()
    index = {n: j for j, n in enumerate(skel.joint_names) if skel.channels[j]}
    n_ch = skel.n_channels
    degrees = asf.angle_unit == "deg"
    frames = []
    current = None
    seen = set()
    frame_line = 0
    expected_id = None

    def close(lineno):
        missing = [n for n in index if n not in seen]
        if missing:
            raise DataFileError(path, f"line {lineno}: frame {expected_id - 1} lacks bones {missing}")

    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    for k, raw in enumerate(lines):
        lineno = k + 1
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            word = line[1:].upper()
            if word == "DEGREES":
                degrees = True
            elif word == "RADIANS":
                degrees = False
            continue
        t = line.split()
        if len(t) == 1 and t[0].isdigit():
            if current is not None:
                close(lineno)
                frames.append(current)
            fid = int(t[0])
            if expected_id is not None and fid != expected_id:
                raise DataFileError(path, f"line {lineno}: frame number {fid}; expected {expected_id}")
            expected_id = fid + 1
            current = np.full(n_ch, np.nan)
            seen = set()
            frame_line = lineno
            continue
        if current is None:
            raise DataFileError(path, f"line {lineno}: bone values before the first frame number")
        name = t[0]
        if name not in index:
            raise DataFileError(path, f"line {lineno}: bone {name!r} is not a bone with dof in {asf.path}")
        j = index[name]
        nd = len(skel.channels[j])
        if len(t) - 1 != nd:
            raise DataFileError(path, f"line {lineno}: bone {name!r} has {len(t) - 1} values; expected {nd}")
        vals = _floats(path, lineno, t[1:], nd, f"bone {name!r}")
        if name in seen:
            raise DataFileError(path, f"line {lineno}: bone {name!r} given twice in the frame of line {frame_line}")
        seen.add(name)
        current[starts[j] : starts[j] + nd] = vals
    if current is None:
        raise DataFileError(path, "no frames in AMC file")
    close(len(lines))
    frames.append(current)
    motion = np.array(frames)
    if not degrees:
        rot = np.array([ch.endswith("rotation") for chans in skel.channels for ch in chans])
        motion[:, rot] = np.rad2deg(motion[:, rot])
    if not np.all(np.isfinite(motion)):
        r, c = np.argwhere(~np.isfinite(motion))[0]
        raise DataFileError(path, f"frame {r}, value {c + 1} is not finite")
    return AMCData(asf, motion, float(frame_time), str(path))


def asf_positions(asf, motion):
    """World joint positions (F, J, 3) for AMC values ``motion`` (F, C) in degrees."""
    skel = asf.skeleton
    motion = np.asarray(motion, dtype=float)
    F = motion.shape[0]
    J = len(skel.joint_names)
    R = np.empty((F, J, 3, 3))
    T = np.broadcast_to(skel.offsets, (F, J, 3)).copy()
    for j, (chans, start) in enumerate(zip(skel.channels, skel.channel_starts())):
        order, cols = "", []
        for k, ch in enumerate(chans):
            if ch.endswith("rotation"):
                order += ch[0]
                cols.append(start + k)
            else:
                T[:, j, "XYZ".index(ch[0])] += motion[:, start + k]
        M = _order_matrix(order, motion[:, cols])
        C = asf.axes[j]
        R[:, j] = C @ M @ C.T
    return forward_kinematics(skel.parents, R, T)[0]
