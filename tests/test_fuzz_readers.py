"""Fuzz test of the motion-capture readers: seeded mutants of the vendored CMU BVH files and the test files.

Each mutant applies one to three mutations: truncation at a random offset, a token deleted, duplicated or
replaced by random text (or by another keyword of the format), lines shuffled. Every mutant either parses,
with its frame count consistent with the rows it has, or raises an InputError (DataFileError) naming the file
and the line; no other exception. The fast tier runs 500 mutants per format (seconds); ``-m slow`` runs
5,000 per format from other seeds. ``python tests/test_fuzz_readers.py [n]`` prints the counts.
"""

import re
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from bsrbench.errors import DataFileError
from bsrbench.mocap import parse_amc, parse_asf, parse_bvh

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
CMU = ROOT / "resources" / "cmu-mocap"
KEEP_FRAMES = (
    12  # vendored BVH files are cut to this many frames (with a matching Frames: line) to stay fast
)

KEYWORDS = {
    "bvh": [
        "HIERARCHY",
        "ROOT",
        "JOINT",
        "End",
        "Site",
        "{",
        "}",
        "OFFSET",
        "CHANNELS",
        "3",
        "6",
        "Xrotation",
        "MOTION",
        "Frames:",
        "Frame Time:",
        "0.0083333",
    ],
    "asf": [
        ":root",
        ":bonedata",
        ":hierarchy",
        ":units",
        "begin",
        "end",
        "name",
        "dof",
        "limits",
        "(",
        ")",
        "axis",
        "XYZ",
        "rx",
        "inf",
        "bodymass",
        "root",
        ",",
    ],
    "amc": [":DEGREES", ":RADIANS", "1", "2", "root", "lfemur", "lradius", "#", ","],
}
NOISE = "abcXYZ019.-+e_,:#(){} \t\u00e9\u00b3\u0661\ufeff"


def _bvh_sources():
    out = {"01_01_equivalent.bvh": (DATA / "01_01_equivalent.bvh").read_text()}
    for p in sorted(CMU.glob("*.bvh")):
        lines = p.read_text().splitlines()
        k = next(i for i, ln in enumerate(lines) if ln.lower().startswith("frame time"))
        head = [
            f"Frames: {KEEP_FRAMES}" if ln.lower().startswith("frames:") else ln
            for ln in lines[: k + 1]
        ]
        out[p.name] = "\n".join(head + lines[k + 1 : k + 1 + KEEP_FRAMES]) + "\n"
    return out


def sources(fmt):
    """{file name: text} of the files the mutants of ``fmt`` start from."""
    if fmt == "bvh":
        return _bvh_sources()
    name = {"asf": "01.asf", "amc": "01_01.amc"}[fmt]
    return {name: (DATA / name).read_text()}


def mutate(text, fmt, rng):
    """One random mutation of ``text``: truncate, delete/duplicate/replace a token, or shuffle lines."""
    kind = rng.choice(["truncate", "delete", "duplicate", "replace", "replace", "shuffle"])
    if kind == "truncate":
        return text[: int(rng.integers(0, len(text) + 1))]
    if kind == "shuffle":
        lines = text.splitlines(keepends=True)
        if len(lines) < 2:
            return text
        a = int(rng.integers(0, len(lines) - 1))
        b = min(len(lines), a + int(rng.integers(2, 12)))
        if rng.random() < 0.1:
            a, b = 0, len(lines)
        window = lines[a:b]
        rng.shuffle(window)
        return "".join(lines[:a] + window + lines[b:])
    spans = [m.span() for m in re.finditer(r"\S+", text)]
    if not spans:
        return text
    s, e = spans[int(rng.integers(0, len(spans)))]
    if kind == "delete":
        return text[:s] + text[e:]
    if kind == "duplicate":
        return text[:e] + " " + text[s:e] + text[e:]
    if rng.random() < 0.4:
        new = str(rng.choice(KEYWORDS[fmt]))
    else:
        new = "".join(rng.choice(list(NOISE), size=int(rng.integers(1, 8))))
    return text[:s] + new + text[e:]


def _frames_declared_and_rows(text):
    """BVH, read independently: the Frames: value and the number of non-empty lines after Frame Time."""
    lines = re.split(r"\r\n|\r|\n", text.lstrip("\ufeff"))
    k = next(
        i for i, ln in enumerate(lines) if " ".join(ln.split()).lower().startswith("frame time")
    )
    frames = next(
        int(ln.split(":", 1)[1]) for ln in lines[:k] if ln.strip().lower().startswith("frames")
    )
    return frames, sum(1 for ln in lines[k + 1 :] if ln.strip())


def check_parsed(fmt, text, result):
    """A mutant that parses has a frame count consistent with the rows it holds."""
    if fmt == "bvh":
        frames, rows = _frames_declared_and_rows(text)
        assert result.n_frames == frames == rows
        assert result.motion.shape == (rows, result.skeleton.n_channels)
    elif fmt == "amc":
        lines = re.split(r"\r\n|\r|\n", text.lstrip("\ufeff"))
        ids = [ln.split()[0] for ln in lines if re.fullmatch(r"\s*[0-9]+\s*", ln.split("#")[0])]
        assert result.n_frames == len(ids) == int(ids[-1]) - int(ids[0]) + 1
        assert np.isfinite(result.motion).all()
    else:
        bones = [
            j
            for j, n in enumerate(result.skeleton.joint_names)
            if j > 0 and not result.skeleton.end_site[j]
        ]
        code = "\n".join(ln.split("#")[0] for ln in re.split(r"\r\n|\r|\n", text))
        bonedata = re.split(r"(?im)^[ \t]*:hierarchy", code)[0]
        named = re.findall(r"(?im)^[ \t]*name[ \t,]+[^\s,]+[ \t,]*$", bonedata)
        assert len(bones) == len(named)


def fuzz(fmt, n, seed, tmp_path):
    """Run ``n`` mutants of format ``fmt``; return Counter(parsed, input_error, other) and the other errors."""
    rng = np.random.default_rng(seed)
    srcs = sources(fmt)
    names = sorted(srcs)
    asf = parse_asf(DATA / "01.asf") if fmt == "amc" else None
    counts, others = Counter(), []
    for i in range(n):
        name = names[i % len(names)]
        text = srcs[name]
        for _ in range(int(rng.integers(1, 4))):
            text = mutate(text, fmt, rng)
        path = tmp_path / name
        path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
        try:
            if fmt == "bvh":
                result = parse_bvh(path)
            elif fmt == "asf":
                result = parse_asf(path)
            else:
                result = parse_amc(path, asf)
        except DataFileError as exc:
            n_lines = len(re.split(r"\r\n|\r|\n", text))
            ok = (
                exc.path == str(path)
                and isinstance(exc.line, int)
                and 1 <= exc.line <= n_lines
                and str(exc).startswith(f"{path}: line {exc.line}")
            )
            counts["input_error" if ok else "other"] += 1
            if not ok:
                others.append((name, i, f"no file/line: {exc}"))
        except Exception as exc:
            counts["other"] += 1
            others.append((name, i, f"{type(exc).__name__}: {exc}"))
        else:
            try:
                check_parsed(fmt, text, result)
            except AssertionError as exc:
                counts["other"] += 1
                others.append((name, i, f"parsed with inconsistent frames: {exc}"))
            else:
                counts["parsed"] += 1
    counts["mutants"] = n
    return counts, others


@pytest.mark.parametrize("fmt", ["bvh", "asf", "amc"])
def test_fuzz_sample(fmt, tmp_path):
    counts, others = fuzz(fmt, 500, seed=11, tmp_path=tmp_path)
    assert not others, others[:5]
    assert counts["input_error"] > 100  # the mutations do break files (not a test that cannot fail)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("fmt", ["bvh", "asf", "amc"])
def test_fuzz_long(fmt, seed, tmp_path):
    counts, others = fuzz(fmt, 5000, seed=1000 + seed, tmp_path=tmp_path)
    assert not others, others[:5]


if __name__ == "__main__":
    import tempfile

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 500
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 11
    for fmt in ("bvh", "asf", "amc"):
        with tempfile.TemporaryDirectory() as d:
            counts, others = fuzz(fmt, n, seed, Path(d))
        print(
            f"{fmt}: mutants {counts['mutants']}, parsed {counts['parsed']}, InputErrors {counts['input_error']}, "
            f"other exceptions {counts['other']}"
        )
        for o in others[:10]:
            print("   ", o)
