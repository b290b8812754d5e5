"""The readers accept what BVH (Biovision) and ASF/AMC (Acclaim 1.10) allow, and reject anything else with an
InputError naming the file and the line (issue 11's four cases first)."""

from pathlib import Path

import numpy as np
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.mocap import parse_amc, parse_asf, parse_bvh

DATA = Path(__file__).resolve().parent / "data"
BVH = (DATA / "01_01_equivalent.bvh").read_text()
ASF = (DATA / "01.asf").read_text()
AMC = (DATA / "01_01.amc").read_text()


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    return p


def _line_of(text, needle):
    return text[: text.index(needle)].count("\n") + 1


# ------------------------------------------------------------------------------------------ the cases
def test_bvh_with_a_byte_order_mark_parses_like_without(tmp_path):
    """Before: "line 1: expected 'HIERARCHY' at the start of a BVH file" (the BOM was part of the keyword)."""
    plain = parse_bvh(DATA / "01_01_equivalent.bvh")
    bom = parse_bvh(_write(tmp_path, "bom.bvh", b"\xef\xbb\xbf" + BVH.encode()))
    assert bom.skeleton.joint_names == plain.skeleton.joint_names
    np.testing.assert_array_equal(bom.motion, plain.motion)


def test_asf_limits_with_commas(tmp_path):
    """Before: "'-20.0,' is not a number"; Acclaim treats commas as white space."""
    text = ASF.replace("limits (-20.0 45.0)", "limits (-20.0, 45.0)").replace(
        "(-70.0 70.0)", "(-70.0,70.0)"
    )
    assert text != ASF
    asf = parse_asf(_write(tmp_path, "01.asf", text))
    assert asf.limits == parse_asf(DATA / "01.asf").limits
    assert asf.limits["lfemur"][1] == (-70.0, 70.0)


def test_asf_optional_bodymass_and_cofmass(tmp_path):
    """Before: "unknown bone field 'bodymass'"."""
    text = ASF.replace("name lowerback\n", "name lowerback\n     bodymass 2.5\n     cofmass 0.4\n")
    asf = parse_asf(_write(tmp_path, "01.asf", text))
    assert asf.masses["lowerback"] == {"bodymass": 2.5, "cofmass": 0.4}
    np.testing.assert_array_equal(asf.skeleton.offsets, parse_asf(DATA / "01.asf").skeleton.offsets)


def test_asf_name_without_value_names_file_and_line(tmp_path):
    """Before: a bare IndexError naming neither the file nor the line."""
    text = ASF.replace("name lowerback\n", "name\n")
    with pytest.raises(
        InputError, match=rf"01\.asf: line {_line_of(ASF, 'name lowerback')}: name needs one word"
    ):
        parse_asf(_write(tmp_path, "01.asf", text))


@pytest.mark.parametrize(
    "old, new, message",
    [
        (
            "direction 0 1 0",
            "direction 0 0 0",
            r"direction 0 0 0 is the zero vector; expected a unit vector",
        ),
        (
            "direction 0 1 0",
            "direction 0 2 0",
            r"direction 0 2 0 has norm 2; expected a unit vector .*e\.g\. direction 0 1 0",
        ),
        (
            "direction 0 1 0",
            "direction 1 1 0",
            r"direction 1 1 0 has norm 1\.41421; .*e\.g\. direction 0\.707107 0\.707107 0",
        ),
        (
            "limits (-20.0 45.0)",
            "limits (45.0 -20.0)",
            r"limits \(45\.0 -20\.0\): the lower bound 45 is above the upper bound -20; expected \(lo hi\) with lo <= hi",
        ),
        (
            "limits (-20.0 45.0)",
            "limits (-20.0 45.0)\n           (inf -inf)",
            r"limits \(inf -inf\): the lower bound inf is above the upper bound -inf",
        ),
    ],
    ids=[
        "zero-direction",
        "direction-norm-2",
        "direction-unnormalised",
        "inverted-limits",
        "inverted-continued",
    ],
)
def test_asf_bad_direction_or_inverted_limits_names_file_line_and_values(
    tmp_path, old, new, message
):
    """Before: a zero direction was taken as is (the child joint sat on its parent), a non-unit one was normalised
    silently, and inverted limits were kept; now each is a DataFileError naming the file, the line and the values."""
    text = ASF.replace(old, new, 1)
    line = _line_of(ASF, old) + new.count("\n")
    p = _write(tmp_path, "01.asf", text)
    with pytest.raises(DataFileError, match=message) as err:
        parse_asf(p)
    assert err.value.line == line and str(err.value).startswith(f"{p}: line {line}: ")


def test_asf_direction_rounded_to_six_decimals_is_normalised(tmp_path):
    """A unit vector printed with 6 decimals (CMU's files) is accepted and normalised exactly."""
    text = ASF.replace("direction 0 1 0", "direction 0.707107 0.707107 0", 1)
    asf = parse_asf(_write(tmp_path, "01.asf", text))
    ref = parse_asf(DATA / "01.asf")
    moved = [
        j
        for j in range(len(ref.skeleton.offsets))
        if not np.array_equal(asf.skeleton.offsets[j], ref.skeleton.offsets[j])
    ]
    assert moved  # the child joints of the first bone moved
    for j in moved:
        np.testing.assert_allclose(
            np.linalg.norm(asf.skeleton.offsets[j]),
            np.linalg.norm(ref.skeleton.offsets[j]),
            rtol=1e-12,
        )


# ----------------------------------------------------------------------------------- each kind, as a whole
def _windows(text):
    return b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode()


@pytest.mark.parametrize("variant", ["crlf+bom", "cr", "tabs", "lower-case keywords"])
def test_bvh_text_variants(tmp_path, variant):
    text = {
        "crlf+bom": _windows(BVH),
        "cr": BVH.replace("\n", "\r"),
        "tabs": BVH.replace("  ", "\t").replace(" ", "\t"),
        "lower-case keywords": BVH.replace("HIERARCHY", "hierarchy")
        .replace("ROOT", "root")
        .replace("JOINT", "joint")
        .replace("End Site", "END SITE")
        .replace("OFFSET", "offset")
        .replace("CHANNELS", "channels")
        .replace("rotation", "ROTATION")
        .replace("MOTION", "motion")
        .replace("Frame Time:", "FRAME  TIME:")
        .replace("Frames:", "frames:"),
    }[variant]
    got = parse_bvh(_write(tmp_path, "v.bvh", text))
    ref = parse_bvh(DATA / "01_01_equivalent.bvh")
    assert got.skeleton.joint_names == ref.skeleton.joint_names
    assert got.skeleton.channels == ref.skeleton.channels  # canonical channel names
    np.testing.assert_array_equal(got.motion, ref.motion)


@pytest.mark.parametrize("variant", ["crlf+bom", "tabs", "commas", "upper-case keywords"])
def test_asf_amc_text_variants(tmp_path, variant):
    def change(text, amc):
        if variant == "crlf+bom":
            return _windows(text)
        if variant == "tabs":
            return text.replace(" ", "\t")
        if variant == "commas":  # commas as separators everywhere, as the format allows
            return "\n".join(
                ln if ln.lstrip().startswith((":", "#")) else ", ".join(ln.split())
                for ln in text.splitlines()
            )
        if amc:
            return text.replace(":DEGREES", ":degrees").replace(
                ":FULLY-SPECIFIED", ":fully-specified"
            )
        return "\n".join(
            ln.upper()
            if ln.lstrip().startswith(":")
            else " ".join(
                w.upper()
                if w
                in (
                    "begin",
                    "end",
                    "name",
                    "direction",
                    "length",
                    "axis",
                    "dof",
                    "limits",
                    "id",
                    "order",
                    "position",
                    "orientation",
                    "mass",
                    "angle",
                )
                else w
                for w in ln.split()
            )
            for ln in text.splitlines()
        )

    _write(tmp_path, "01.asf", change(ASF, False))
    _write(tmp_path, "01_01.amc", change(AMC, True))
    got = parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf")
    ref = parse_amc(DATA / "01_01.amc", DATA / "01.asf")
    assert got.skeleton.joint_names == ref.skeleton.joint_names
    assert got.asf.limits == ref.asf.limits
    np.testing.assert_array_equal(got.motion, ref.motion)


@pytest.mark.parametrize(
    "reader, name, text, message",
    [
        (
            "bvh",
            "x.bvh",
            BVH.replace("Frames: 3", "Frames: 2"),
            r"more motion rows than 'Frames: 2'",
        ),
        (
            "bvh",
            "x.bvh",
            BVH.replace("Frames: 3", "Frames: ³"),
            r"Frames: '³' is not a whole number",
        ),
        (
            "bvh",
            "x.bvh",
            BVH.replace("OFFSET", "OFFSET 1_0", 1).replace("1_0 0", "1_0", 1),
            r"'1_0' is not a number",
        ),
        ("bvh", "x.bvh", BVH.replace("Zrotation", "Wrotation", 1), r"unknown channel 'Wrotation'"),
        (
            "bvh",
            "x.bvh",
            BVH.replace("MOTION", "MOTION\nFrames: 3", 1),
            r"expected 'Frame Time: <value>'",
        ),
        (
            "asf",
            "01.asf",
            ASF.replace(":hierarchy", ":hierarchy\n  begin\n    root lhipjoint\n  end\n:skeleton"),
            r"unknown section ':skeleton'",
        ),
        (
            "asf",
            "01.asf",
            ASF.replace("limits (-20.0 45.0)", "limits (-20.0 45.0", 1),
            r"expected limits as",
        ),
        ("asf", "01.asf", ASF.replace("  mass 1.0", "  weight 1.0"), r"unknown unit 'weight'"),
        (
            "amc",
            "01_01.amc",
            AMC.replace(":DEGREES", ":GRADS"),
            r"expected :FULLY-SPECIFIED, :DEGREES",
        ),
        (
            "amc",
            "01_01.amc",
            AMC.replace("lradius 45.0", "lradius 1e999", 1),
            r"'1e999' is not a number",
        ),
    ],
    ids=[
        "bvh-rows",
        "bvh-superscript",
        "bvh-underscore",
        "bvh-channel",
        "bvh-header",
        "asf-section",
        "asf-limits",
        "asf-unit",
        "amc-keyword",
        "amc-overflow",
    ],
)
def test_anything_else_is_an_input_error_with_file_and_line(tmp_path, reader, name, text, message):
    p = _write(tmp_path, name, text)
    with pytest.raises(DataFileError, match=message) as err:
        if reader == "bvh":
            parse_bvh(p)
        elif reader == "asf":
            parse_asf(p)
        else:
            _write(tmp_path, "01.asf", ASF)
            parse_amc(p, tmp_path / "01.asf")
    e = err.value
    assert e.path == str(p) and isinstance(e.line, int) and 1 <= e.line <= text.count("\n") + 2
    assert str(e).startswith(f"{p}: line {e.line}")
