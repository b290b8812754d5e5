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
* ``direction`` must be a unit vector up to the rounding of its printed digits (norm within
  :data:`DIRECTION_TOLERANCE` of 1; it is then normalised exactly). A zero or markedly non-unit vector is an
  error naming the file and line: the length is the ``length`` field, and common readers (CMU's ASF/AMC player,
  AMCParser) multiply the vector as written by it, so such a file has no single meaning. ``limits`` intervals
  must have ``lo <= hi``.

Kinematics (the usual ASF/AMC rule): the bone's world rotation is ``G_b = G_parent C_b M_b C_b^-1`` with
``M_b`` the motion rotation built from the dof values, rotations applied in the listed order (``rx ry rz``
gives ``M = Rz Ry Rx``); the bone's end is its start plus ``G_b (length_b direction_b)``.
So every bone becomes a joint at its start with offset ``length_p direction_p`` from its parent bone and local
rotation ``C M C^-1``, and the ordinary tree forward kinematics of :mod:`.skeleton` applies. A BVH whose joints
use ``Zrotation Yrotation Xrotation`` and these offsets gives the same world positions when every axis is zero.
"""

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ._text import first_bad_number, is_whole, read_lines, tokens
from .skeleton import Skeleton, axis_rotation, euler_matrix, forward_kinematics

_DOF_CHANNEL = {
    "rx": "Xrotation",
    "ry": "Yrotation",
    "rz": "Zrotation",
    "tx": "Xposition",
    "ty": "Yposition",
    "tz": "Zposition",
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
    ``axes`` (J, 3, 3): each joint's frame C; ``limits``: bone name -> list of (lo, hi) per dof;
    ``masses``: bone name -> its optional ``bodymass``/``cofmass`` fields (read and kept, not used).
    """

    skeleton: Skeleton
    axes: np.ndarray
    root_order: tuple
    length_unit: float
    angle_unit: str
    limits: dict = field(default_factory=dict)
    path: str = ""
    masses: dict = field(default_factory=dict)


def _fail(path, lineno, message):
    return DataFileError(path, f"line {lineno}: {message}", line=lineno)


def _floats(path, lineno, tokens_, n, what):
    if len(tokens_) != n:
        raise _fail(
            path,
            lineno,
            f"{what} needs {n} number{'s' if n > 1 else ''}, found {len(tokens_)} values",
        )
    bad = first_bad_number(tokens_)
    if bad is not None:
        raise _fail(path, lineno, f"{what}: {tokens_[bad][:40]!r} is not a number")
    return [float(x) for x in tokens_]


#: ASF sections (Acclaim 1.10); ``:skin`` names skin files and is ignored.
_SECTIONS = ("version", "name", "units", "documentation", "root", "bonedata", "hierarchy", "skin")
_BONE_FIELDS = ("id", "name", "direction", "length", "axis", "dof", "limits", "bodymass", "cofmass")
_LIMIT = re.compile(r"\(\s*([^\s()]+)\s+([^\s()]+)\s*\)")
_INF = {"inf": float("inf"), "+inf": float("inf"), "-inf": -float("inf")}


#: How far from 1 the norm of a bone's ``direction`` may be: the rounding of a unit vector printed with a few
#: decimals (CMU's files print 6 and are unit to 1e-6).
DIRECTION_TOLERANCE = 1e-3


def _direction(path, lineno, tokens_):
    """A bone's ``direction``: a unit vector (normalised exactly when within :data:`DIRECTION_TOLERANCE` of unit).

    The spec gives the bone's length in its own field, and the common readers (CMU's C++ ASF/AMC player, the
    AMCParser of CalciferZh) place the bone's end at ``length * direction`` with the vector as written, so a
    markedly non-unit vector would make this reader and those disagree on the bone's length: it is an error,
    like the zero vector (no direction at all)."""
    d = np.array(_floats(path, lineno, tokens_, 3, "direction"))
    nrm = float(np.linalg.norm(d))
    shown = " ".join(tokens_)
    if not nrm > 1e-6:
        raise _fail(
            path,
            lineno,
            f"direction {shown} is the zero vector; expected a unit vector (the bone's "
            f"direction in the default pose)",
        )
    if abs(nrm - 1.0) > DIRECTION_TOLERANCE:
        unit = " ".join(f"{x:.6g}" for x in d / nrm)
        raise _fail(
            path,
            lineno,
            f"direction {shown} has norm {nrm:.6g}; expected a unit vector (norm 1 within "
            f"{DIRECTION_TOLERANCE:g}; the bone's length is the 'length' field), e.g. "
            f"direction {unit}",
        )
    return d / nrm


def _limits(path, lineno, body):
    """The ``(lo hi)`` intervals of one limits line (commas already blanked); ``inf`` allowed; ``lo <= hi``."""
    out, pos = [], 0
    for m in _LIMIT.finditer(body):
        if body[pos : m.start()].strip():
            break
        lo_hi = []
        for x in m.groups():
            if x.lower() in _INF:
                lo_hi.append(_INF[x.lower()])
            else:
                lo_hi += _floats(path, lineno, [x], 1, "limits")
        if lo_hi[0] > lo_hi[1]:
            raise _fail(
                path,
                lineno,
                f"limits ({m.group(1)} {m.group(2)}): the lower bound {lo_hi[0]:g} is above the "
                f"upper bound {lo_hi[1]:g}; expected (lo hi) with lo <= hi",
            )
        out.append(tuple(lo_hi))
        pos = m.end()
    if not out or body[pos:].strip():
        raise _fail(
            path, lineno, f"expected limits as '(lo hi)' intervals, found {body.strip()[:60]!r}"
        )
    return out


def parse_asf(path):
    """Read an ASF skeleton file into an :class:`ASFSkeleton`.

    Accepts what Acclaim 1.10 allows: a UTF-8 byte-order mark, LF/CRLF/CR line ends, tabs, commas as white
    space (``limits (-20.0, 45.0)``), keywords in any letter case, ``#`` comments, the optional bone fields
    (``id``, ``axis``, ``dof``, ``limits``, ``bodymass``, ``cofmass``) and the ``:version``, ``:name``,
    ``:units`` (``mass``, ``length``, ``angle``), ``:documentation`` and ``:skin`` sections.
    Raises :class:`~bsrbench.errors.DataFileError` (an InputError) naming the file and the line (``.line``) and
    what was expected for anything else.
    """
    path = Path(path)
    lines = read_lines(path, "an ASF skeleton file")
    n_lines = max(len(lines), 1)
    section = None
    seen = {}
    units = {"length": 1.0, "angle": "deg"}
    root = {
        "order": None,
        "axis": "XYZ",
        "position": [0.0, 0.0, 0.0],
        "orientation": [0.0, 0.0, 0.0],
    }
    bones = {}
    bone = None
    last_field = None
    hierarchy = []
    hier_state = None  # None, "open" after 'begin', "closed" after 'end'
    for k, raw in enumerate(lines):
        lineno = k + 1
        line = raw.split("#", 1)[0]
        t = tokens(line, commas=True)
        if not t:
            continue
        key = t[0].lower()
        if key.startswith(":"):
            name = key[1:]
            if name not in _SECTIONS:
                raise _fail(
                    path,
                    lineno,
                    f"unknown section {t[0][:40]!r}; expected one of {', '.join(':' + x for x in _SECTIONS)}",
                )
            if bone is not None:
                raise _fail(path, lineno, f"bone of line {bone['line']} has no 'end' before {t[0]}")
            if name in seen:
                raise _fail(
                    path, lineno, f"a second {t[0]} section (the first is on line {seen[name]})"
                )
            if name in ("version", "name") and len(t) < 2:
                raise _fail(path, lineno, f"{t[0]} needs a value")
            if name in ("units", "documentation", "root", "bonedata", "hierarchy") and len(t) != 1:
                raise _fail(
                    path, lineno, f"expected {t[0]} alone on its line, found {line.strip()[:60]!r}"
                )
            seen[name] = lineno
            section = name
            continue
        if section == "documentation":
            continue
        if section in (None, "version", "name", "skin"):
            raise _fail(
                path,
                lineno,
                f"unexpected {t[0][:40]!r}; expected a section keyword such as :units or :root",
            )
        if section == "units":
            if key in ("length", "mass"):
                value = _floats(path, lineno, t[1:], 1, key)[0]
                if not value > 0:
                    raise _fail(path, lineno, f"{key} unit must be > 0, found {value}")
                if key == "length":
                    units["length"] = value
            elif key == "angle":
                if len(t) != 2 or t[1].lower() not in ("deg", "rad"):
                    raise _fail(
                        path,
                        lineno,
                        f"angle unit must be 'deg' or 'rad', found {' '.join(t[1:])[:40]!r}",
                    )
                units["angle"] = t[1].lower()
            else:
                raise _fail(
                    path, lineno, f"unknown unit {t[0][:40]!r}; expected mass, length or angle"
                )
        elif section == "root":
            if key == "order":
                order = tuple(x.upper() for x in t[1:])
                bad = [x for x in order if x.lower() not in _DOF_CHANNEL]
                if bad or not order or len(set(order)) != len(order):
                    raise _fail(
                        path,
                        lineno,
                        f"root order {' '.join(t[1:])[:60]!r}; expected distinct TX TY TZ RX RY RZ",
                    )
                root["order"] = order
            elif key == "axis":
                if len(t) != 2 or sorted(t[1].upper()) != ["X", "Y", "Z"]:
                    raise _fail(
                        path,
                        lineno,
                        f"root axis must be a permutation of XYZ, found {' '.join(t[1:])[:40]!r}",
                    )
                root["axis"] = t[1].upper()
            elif key in ("position", "orientation"):
                root[key] = _floats(path, lineno, t[1:], 3, key)
            else:
                raise _fail(
                    path,
                    lineno,
                    f"unknown root field {t[0][:40]!r}; expected order, axis, position or orientation",
                )
        elif section == "bonedata":
            if key == "begin":
                if bone is not None:
                    raise _fail(
                        path,
                        lineno,
                        f"'begin' inside the bone of line {bone['line']}; expected 'end'",
                    )
                if len(t) != 1:
                    raise _fail(
                        path,
                        lineno,
                        f"expected 'begin' alone on its line, found {line.strip()[:60]!r}",
                    )
                bone = {
                    "dof": (),
                    "limits": [],
                    "axis": [0.0, 0.0, 0.0],
                    "axis_order": "XYZ",
                    "line": lineno,
                }
                last_field = None
                continue
            if bone is None:
                raise _fail(path, lineno, f"{t[0][:40]!r} outside a bone's begin/end")
            if key == "end":
                if len(t) != 1:
                    raise _fail(
                        path,
                        lineno,
                        f"expected 'end' alone on its line, found {line.strip()[:60]!r}",
                    )
                for field_ in ("name", "direction", "length"):
                    if field_ not in bone:
                        raise _fail(
                            path, lineno, f"the bone of line {bone['line']} has no {field_!r}"
                        )
                if bone["limits"] and len(bone["limits"]) != len(bone["dof"]):
                    raise _fail(
                        path,
                        lineno,
                        f"bone {bone['name']!r} has {len(bone['limits'])} limits for {len(bone['dof'])} dof",
                    )
                if bone["name"] in bones or bone["name"] == "root":
                    raise _fail(
                        path, bone["name_line"], f"bone name {bone['name']!r} is used twice"
                    )
                bones[bone["name"]] = bone
                bone = None
                continue
            if key.startswith("(") and last_field == "limits":  # a limits line continues
                bone["limits"] += _limits(path, lineno, line.replace(",", " "))
                continue
            if key not in _BONE_FIELDS:
                raise _fail(
                    path,
                    lineno,
                    f"unknown bone field {t[0][:40]!r}; expected one of {', '.join(_BONE_FIELDS)}",
                )
            if key in bone and key not in ("dof", "limits", "axis"):
                raise _fail(path, lineno, f"a second {key!r} in the bone of line {bone['line']}")
            last_field = key
            if key == "id":
                if len(t) != 2:
                    raise _fail(path, lineno, f"id needs one value, found {len(t) - 1}")
                bone["id"] = t[1]
            elif key == "name":
                if len(t) != 2:
                    raise _fail(
                        path, lineno, f"name needs one word (the bone's name), found {len(t) - 1}"
                    )
                bone["name"], bone["name_line"] = t[1], lineno
            elif key == "direction":
                bone["direction"] = _direction(path, lineno, t[1:])
            elif key == "length":
                bone["length"] = _floats(path, lineno, t[1:], 1, "length")[0]
                if bone["length"] < 0:
                    raise _fail(path, lineno, f"length must be >= 0, found {bone['length']}")
            elif key in ("bodymass", "cofmass"):
                bone[key] = _floats(path, lineno, t[1:], 1, key)[0]
            elif key == "axis":
                if len(t) != 5 or sorted(t[4].upper()) != ["X", "Y", "Z"]:
                    raise _fail(
                        path,
                        lineno,
                        f"bone axis must be 'axis ax ay az XYZ', found {line.strip()[:60]!r}",
                    )
                bone["axis"] = _floats(path, lineno, t[1:4], 3, "axis")
                bone["axis_order"] = t[4].upper()
            elif key == "dof":
                dof = tuple(x.lower() for x in t[1:])
                bad = [x for x in dof if x not in _DOF_CHANNEL]
                if bad or not dof or len(set(dof)) != len(dof):
                    raise _fail(
                        path,
                        lineno,
                        f"dof {' '.join(t[1:])[:60]!r}; expected distinct rx ry rz tx ty tz",
                    )
                bone["dof"] = dof
            elif key == "limits":
                body = line.replace(",", " ")
                body = body[body.lower().index("limits") + len("limits") :]
                bone["limits"] = _limits(path, lineno, body)
        elif section == "hierarchy":
            if key == "begin" and len(t) == 1 and hier_state is None:
                hier_state = "open"
            elif key == "end" and len(t) == 1 and hier_state == "open":
                hier_state = "closed"
            elif hier_state != "open":
                want = (
                    "'begin'" if hier_state is None else "the next section (':hierarchy' is closed)"
                )
                raise _fail(path, lineno, f"expected {want}, found {line.strip()[:60]!r}")
            elif len(t) < 2:
                raise _fail(
                    path,
                    lineno,
                    f"a hierarchy line names a parent and its children, found {t[0][:40]!r}",
                )
            else:
                hierarchy.append((lineno, t[0], t[1:]))
    if bone is not None:
        raise _fail(
            path, n_lines, f"file ends inside the bone of line {bone['line']}; expected 'end'"
        )
    if hier_state == "open":
        raise _fail(path, n_lines, "file ends inside ':hierarchy'; expected 'end'")
    if root["order"] is None:
        raise _fail(path, n_lines, "file ends without a ':root' section with an 'order' line")
    if not bones:
        raise _fail(path, n_lines, "file ends without bones in ':bonedata'")

    parent_of = {}
    children = {"root": []}
    placed_on = {}
    for lineno, p, kids in hierarchy:
        if p != "root" and p not in bones:
            raise _fail(path, lineno, f"hierarchy names unknown bone {p!r}")
        for c in kids:
            if c not in bones:
                raise _fail(path, lineno, f"hierarchy names unknown bone {c!r}")
            if c in parent_of:
                raise _fail(path, lineno, f"bone {c!r} has two parents")
            parent_of[c] = p
            placed_on[c] = lineno
            children.setdefault(p, []).append(c)
    missing = [b for b in bones if b not in parent_of]
    if missing:
        raise _fail(
            path, bones[missing[0]]["line"], f"bone(s) {missing} not placed in ':hierarchy'"
        )
    reached, todo = set(), ["root"]
    while todo:
        for c in children.get(todo.pop(), []):
            reached.add(c)
            todo.append(c)
    loose = [b for b in bones if b not in reached]
    if loose:
        raise _fail(
            path, placed_on[loose[0]], f"bone(s) {loose} form a cycle, not a tree below root"
        )

    angle_scale = 1.0 if units["angle"] == "deg" else 180.0 / np.pi
    names = ["root"]
    parents = [-1]
    offsets = [np.array(root["position"], dtype=float)]
    channels = [tuple(_DOF_CHANNEL[x.lower()] for x in root["order"])]
    axes = [_order_matrix(root["axis"], np.array([root["orientation"]]) * angle_scale)[0]]
    end_site = [False]
    limits = {}
    masses = {}

    def visit(name, parent_index):
        b = bones[name]
        names.append(name)
        parents.append(parent_index)
        pb = names[parent_index]
        offsets.append(
            np.zeros(3) if pb == "root" else bones[pb]["length"] * bones[pb]["direction"]
        )
        channels.append(tuple(_DOF_CHANNEL[x] for x in b["dof"]))
        axes.append(_order_matrix(b["axis_order"], np.array([b["axis"]]) * angle_scale)[0])
        end_site.append(False)
        limits[name] = list(b["limits"])
        masses[name] = {k: b[k] for k in ("bodymass", "cofmass") if k in b}
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
        skel,
        np.array(axes),
        root["order"],
        units["length"],
        units["angle"],
        limits,
        str(path),
        masses,
    )


#: Frame time (s) of an AMC motion: the files carry none; CMU captured at 120 Hz.
AMC_FRAME_TIME = 1.0 / 120.0


def amc_frame_count(path):
    """Frames of an AMC file counted from its text alone: the lines that hold one whole number (the frame
    numbers; comments and keyword lines are not frames), as :func:`parse_amc` reads them. A missing file is a
    :class:`~bsrbench.errors.DataFileError`."""
    count = 0
    for raw in read_lines(path, "an AMC motion file"):
        t = tokens(raw.split("#", 1)[0], commas=True)
        count += len(t) == 1 and is_whole(t[0])
    return count


@dataclass
class AMCData:
    """A parsed AMC motion: ``asf`` (its skeleton), ``motion`` (F, C) values in degrees laid out as
    ``asf.skeleton.channels``, ``frame_time`` (s; AMC files carry none: :data:`AMC_FRAME_TIME`), ``path``."""

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


def parse_amc(path, asf, frame_time=AMC_FRAME_TIME):
    """Read an AMC motion file for the skeleton ``asf`` (an :class:`ASFSkeleton` or a path to an ASF file).

    Accepts the same text forms as :func:`parse_asf` (BOM, any line end, tabs, commas as white space, keywords
    ``:FULLY-SPECIFIED``, ``:DEGREES``, ``:RADIANS`` in any letter case). Frames are numbered consecutively;
    every frame must give every bone that has dof, once, with exactly that many values.
    Raises :class:`~bsrbench.errors.DataFileError` naming the file and the line (``.line``) otherwise.
    """
    if not isinstance(asf, ASFSkeleton):
        asf = parse_asf(asf)
    path = Path(path)
    lines = read_lines(path, "an AMC motion file")
    skel = asf.skeleton
    starts = skel.channel_starts()
    index = {n: j for j, n in enumerate(skel.joint_names) if skel.channels[j]}
    n_ch = skel.n_channels
    degrees = asf.angle_unit == "deg"
    frames = []
    current = None
    seen = set()
    frame_line = 0
    frame_id = None

    def close(lineno):
        missing = [n for n in index if n not in seen]
        if missing:
            raise _fail(
                path, lineno, f"frame {frame_id} lacks bones {missing} (frame of line {frame_line})"
            )

    for k, raw in enumerate(lines):
        lineno = k + 1
        t = tokens(raw.split("#", 1)[0], commas=True)
        if not t:
            continue
        if t[0].startswith(":"):
            word = t[0][1:].upper()
            if word not in ("FULLY-SPECIFIED", "DEGREES", "RADIANS") or len(t) != 1:
                raise _fail(
                    path,
                    lineno,
                    f"unexpected {' '.join(t)[:40]!r}; expected :FULLY-SPECIFIED, :DEGREES or :RADIANS",
                )
            if current is not None:
                raise _fail(
                    path,
                    lineno,
                    f"{t[0]} after the first frame; expected it before line {frame_line}",
                )
            if word != "FULLY-SPECIFIED":
                degrees = word == "DEGREES"
            continue
        if len(t) == 1 and is_whole(t[0]):
            fid = int(t[0])
            if current is not None:
                close(lineno)
                frames.append(current)
                if fid != frame_id + 1:
                    raise _fail(path, lineno, f"frame number {fid}; expected {frame_id + 1}")
            frame_id = fid
            current = np.full(n_ch, np.nan)
            seen = set()
            frame_line = lineno
            continue
        if current is None:
            raise _fail(path, lineno, f"expected a frame number before {t[0][:40]!r}")
        name = t[0]
        if name not in index:
            raise _fail(path, lineno, f"bone {name[:40]!r} is not a bone with dof in {asf.path}")
        j = index[name]
        nd = len(skel.channels[j])
        if len(t) - 1 != nd:
            raise _fail(path, lineno, f"bone {name!r} has {len(t) - 1} values; expected {nd}")
        vals = _floats(path, lineno, t[1:], nd, f"bone {name!r}")
        if name in seen:
            raise _fail(
                path, lineno, f"bone {name!r} given twice in the frame of line {frame_line}"
            )
        seen.add(name)
        current[starts[j] : starts[j] + nd] = vals
    if current is None:
        raise _fail(
            path,
            max(len(lines), 1),
            "file ends without a frame (expected a frame number, then bone lines)",
        )
    close(len(lines))
    frames.append(current)
    motion = np.array(frames)
    if not degrees:
        rot = np.array([ch.endswith("rotation") for chans in skel.channels for ch in chans])
        motion[:, rot] = np.rad2deg(motion[:, rot])
    return AMCData(asf, motion, float(frame_time), str(path))


def asf_local_rotations(asf, motion, root_order=None):
    """Local rotations (F, J, 3, 3) ``C M C^-1`` of every joint for values ``motion`` (F, C) in degrees, laid
    out as ``asf.skeleton.channels``; ``M`` applies each joint's rotation dof in their listed order.

    ``root_order`` (three rotation channel names, e.g. ``("Zrotation", "Xrotation", "Yrotation")``), when
    given, reads the root's three rotation values as Euler angles in that order with the first the outermost
    (the BVH convention, ``M = R_first @ R_second @ R_third``): the convention of the root's pose angles
    (:data:`bsrbench.mocap.motion.AMC_ROOT_ORDER`)."""
    skel = asf.skeleton
    motion = np.asarray(motion, dtype=float)
    F = motion.shape[0]
    J = len(skel.joint_names)
    R = np.empty((F, J, 3, 3))
    for j, (chans, start) in enumerate(zip(skel.channels, skel.channel_starts())):
        rot = {ch: start + k for k, ch in enumerate(chans) if ch.endswith("rotation")}
        if j == 0 and root_order is not None:
            if sorted(rot) != sorted(root_order):
                raise DataFileError(
                    asf.path,
                    f"root rotation dof {sorted(rot)} cannot carry Euler angles in the order "
                    f"{list(root_order)}; expected the same three rotations",
                )
            axes = [_AXIS[ch[0]] for ch in root_order]
            M = euler_matrix(axes, motion[:, [rot[ch] for ch in root_order]])
        else:
            M = _order_matrix("".join(ch[0] for ch in rot), motion[:, list(rot.values())])
        C = asf.axes[j]
        R[:, j] = C @ M @ C.T
    return R


def asf_positions(asf, motion, root_order=None):
    """World joint positions (F, J, 3) for AMC values ``motion`` (F, C) in degrees (``root_order``: see
    :func:`asf_local_rotations`)."""
    skel = asf.skeleton
    motion = np.asarray(motion, dtype=float)
    F = motion.shape[0]
    J = len(skel.joint_names)
    T = np.broadcast_to(skel.offsets, (F, J, 3)).copy()
    for j, (chans, start) in enumerate(zip(skel.channels, skel.channel_starts())):
        for k, ch in enumerate(chans):
            if ch.endswith("position"):
                T[:, j, "XYZ".index(ch[0])] += motion[:, start + k]
    return forward_kinematics(skel.parents, asf_local_rotations(asf, motion, root_order), T)[0]
