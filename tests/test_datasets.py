"""Data sets: checksums, the .mat loader, prepared motions, feature files and the CMU download helper."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from bsrbench.datasets import (
    FeatureSet,
    build_mat_features,
    check_features,
    cmu_url,
    count_motion_frames,
    download_cmu_skeleton,
    download_cmu_trial,
    load_feature_mat,
    prepare_motion,
    read_checksums,
    save_features,
    select_frames,
    sha256_file,
    step_frames,
    verify_checksum,
)
from bsrbench.errors import DataFileError, InputError
from bsrbench.io import load_features

ROOT = Path(__file__).resolve().parents[1]
FEAT = ROOT / "resources" / "paper-features"
CMU = ROOT / "resources" / "cmu-mocap"
DATA = Path(__file__).resolve().parent / "data"


def test_checksum_lists_of_vendored_data_verify():
    for sums in (FEAT / "SHA256SUMS", CMU / "SHA256SUMS"):
        table = read_checksums(sums)
        assert table
        for path in table:
            verify_checksum(path, sums)


@pytest.mark.parametrize("name", ["x63", "x4921"])
def test_load_authors_features(name):
    fs = load_feature_mat(FEAT / f"{name}.mat", checksums=FEAT / "SHA256SUMS")
    raw = scipy.io.loadmat(FEAT / f"{name}.mat")
    assert fs.X.shape == (600, 100) and fs.Y.shape == (600, 57)
    np.testing.assert_array_equal(fs.X, raw["X"][:600])
    np.testing.assert_array_equal(fs.Y, raw["Y"][:600, 3:])
    np.testing.assert_array_equal(fs.frames, np.arange(600))
    assert len(fs.angle_names) == 57
    assert fs.meta["sha256"] == [sha256_file(FEAT / f"{name}.mat")]


def test_checksum_mismatch_leaves_no_output(tmp_path):
    mat = tmp_path / "x63.mat"
    shutil.copy(FEAT / "x63.mat", mat)
    good = sha256_file(mat)
    wrong = ("0" if good[0] != "0" else "1") + good[1:]
    (tmp_path / "SHA256SUMS").write_text(f"{wrong}  x63.mat\n")
    out = tmp_path / "out" / "golf.npz"
    with pytest.raises(
        DataFileError, match=rf"x63\.mat: checksum mismatch: expected sha256 {wrong} .* got {good}"
    ):
        build_mat_features(mat, out, checksums=tmp_path / "SHA256SUMS")
    assert not out.exists()
    (tmp_path / "SHA256SUMS").write_text(f"{good}  other.mat\n")
    with pytest.raises(DataFileError, match=r"x63\.mat: has no entry in the checksum list"):
        verify_checksum(mat, tmp_path / "SHA256SUMS")


def test_mat_without_y(tmp_path):
    p = tmp_path / "noy.mat"
    scipy.io.savemat(p, {"X": np.ones((10, 4)), "Z": np.ones((10, 6))})
    with pytest.raises(
        DataFileError, match=r"noy\.mat: has no variable 'Y' \(variables: \['X', 'Z'\]\)"
    ):
        load_feature_mat(p, n_frames=5)
    scipy.io.savemat(p, {"Y": np.ones((10, 6))})
    with pytest.raises(DataFileError, match=r"has no variable 'X'"):
        load_feature_mat(p, n_frames=5)


def test_nan_in_features_is_rejected_without_output(tmp_path):
    p = tmp_path / "nan.mat"
    X = np.ones((10, 4))
    X[3, 2] = np.nan
    scipy.io.savemat(p, {"X": X, "Y": np.zeros((10, 6))})
    out = tmp_path / "nan.npz"
    with pytest.raises(
        InputError, match=r"nan\.mat: X has 1 non-finite value\(s\), first at row 3, column 2"
    ):
        build_mat_features(p, out, n_frames=8)
    assert not out.exists()
    with pytest.raises(InputError, match=r"demo: Y has 1 non-finite"):
        check_features(np.ones((2, 2)), np.array([[0.0, np.inf], [0, 0]]), "demo")


def test_nan_error_names_the_files_row_and_column(tmp_path):
    """After drop_y_columns and a spread frame selection, the error gives the row and column of the file."""
    p = tmp_path / "pose.mat"
    Y = np.zeros((10, 6))
    Y[6, 4] = np.nan  # selected row 2 of rows [0, 3, 6, 9]; column 1 of the 3 kept columns
    scipy.io.savemat(p, {"feat": np.ones((10, 4)), "pose": Y})
    with pytest.raises(
        InputError,
        match=r"pose\.mat: pose has 1 non-finite value\(s\), first at row 6, column 4 "
        r"of the file \(0-based\) \(nan\)",
    ):
        load_feature_mat(
            p, n_frames=4, frame_selection="spread", drop_y_columns=3, x_key="feat", y_key="pose"
        )
    X = np.ones((10, 4))
    X[9, 3] = np.inf
    scipy.io.savemat(p, {"feat": X, "pose": np.zeros((10, 6))})
    with pytest.raises(
        InputError, match=r"pose\.mat: feat has 1 non-finite value\(s\), first at row 9, column 3 "
    ):
        load_feature_mat(
            p, n_frames=4, frame_selection="spread", drop_y_columns=3, x_key="feat", y_key="pose"
        )
    # a features .npz is read whole: its rows and columns are the file's
    npz = tmp_path / "feat.npz"
    Y = np.zeros((5, 3))
    Y[4, 2] = np.nan
    np.savez(
        npz, X=np.ones((5, 2)), Y=Y, frames=np.arange(5), angle_names=np.array(["a", "b", "c"])
    )
    with pytest.raises(
        InputError,
        match=r"feat\.npz: Y has 1 non-finite value\(s\), first at row 4, column 2 \(nan\)",
    ):
        load_features(npz)


def test_mat_shorter_than_frames_asked(tmp_path):
    p = tmp_path / "short.mat"
    scipy.io.savemat(p, {"X": np.ones((10, 4)), "Y": np.zeros((10, 6))})
    with pytest.raises(InputError, match=r"short\.mat: has 10 usable frames but n_frames = 20"):
        load_feature_mat(p, n_frames=20)


def test_select_frames():
    np.testing.assert_array_equal(select_frames(700, 5, "first"), np.arange(5))
    np.testing.assert_array_equal(select_frames(9, 5, "spread"), [0, 2, 4, 6, 8])
    with pytest.raises(
        InputError, match=r"frame_selection must be 'first' or 'spread'; got 'last'"
    ):
        select_frames(9, 5, "last")


def test_select_frames_fewer_than_asked():
    np.testing.assert_array_equal(select_frames(7, 600, "first", fewer="use_all"), np.arange(7))
    with pytest.raises(InputError, match=r"run: has 7 usable frames but n_frames = 600"):
        select_frames(7, 600, "first", source="run")
    with pytest.raises(InputError, match=r"has 7 usable frames"):  # a spread would repeat frames
        select_frames(7, 600, "spread", fewer="use_all")
    with pytest.raises(InputError, match=r"fewer_frames must be one of"):
        select_frames(7, 5, "first", fewer="pad")


def test_step_frames_keeps_file_frames_multiple_of_the_step():
    tf = np.concatenate([np.arange(6, 15), np.arange(6, 10)])  # two trials after skip_frames = 6
    np.testing.assert_array_equal(tf[step_frames(tf, 4)], [8, 12, 8])
    np.testing.assert_array_equal(step_frames(tf, 1), np.arange(len(tf)))
    for bad in (0, 2.0, True):
        with pytest.raises(InputError, match=r"frame_step must be an integer >= 1"):
            step_frames(tf, bad)


def test_prepare_motion_authors_protocol(tmp_path):
    """One frame in 4 of each 120 fps file (file frames 0, 4, 8, ... after skip_frames), trials in order,
    the first n_frames; fewer than asked with fewer_frames use_all; the header count agrees."""
    trials = [CMU / "09_01.bvh", CMU / "09_02.bvh"]  # 149 and 131 frames
    out = tmp_path / "run.npz"
    sel = prepare_motion(
        trials,
        out,
        n_frames=600,
        frame_selection="first",
        skip_frames=6,
        frame_step=4,
        fewer_frames="use_all",
    )
    expect = [(0, f) for f in range(8, 149, 4)] + [(1, f) for f in range(8, 131, 4)]
    assert sel.n_frames == len(expect) == count_motion_frames(trials, 6, 4)
    np.testing.assert_array_equal(np.c_[sel.trial_index, sel.trial_frames], expect)
    with np.load(out) as z:
        assert int(z["frame_step"]) == 4 and str(z["frame_selection"]) == "first"
        assert "one frame in 4 of the 120 fps trials (30 fps)" in str(z["frame_protocol"])
    first = prepare_motion(
        trials,
        tmp_path / "r10.npz",
        n_frames=10,
        frame_selection="first",
        skip_frames=6,
        frame_step=4,
    )
    np.testing.assert_array_equal(first.trial_frames, np.arange(8, 48, 4))
    assert count_motion_frames([CMU / "09_01.bvh", tmp_path / "missing.bvh"], 6, 4) is None


def test_prepare_motion_and_short_trial(tmp_path):
    out = tmp_path / "mocap" / "walk.npz"
    sel = prepare_motion([CMU / "12_02.bvh"], out, n_frames=50, checksums=CMU / "SHA256SUMS")
    with np.load(out) as z:
        assert z["positions"].shape == (50, sel.positions.shape[1], 3)
        assert z["angles"].shape == (50, 57)
        assert list(z["trial_ids"]) == ["12_02"]
        np.testing.assert_array_equal(z["frames"], np.round(np.linspace(0, 672, 50)).astype(int))
        assert str(z["angle_names"][int(z["heading_column"])]) == "hip_Yrotation"
    short = tmp_path / "mocap" / "short.npz"
    with pytest.raises(InputError, match=r"09_01\.bvh: has 148 usable frames but n_frames = 600"):
        prepare_motion([CMU / "09_01.bvh"], short, n_frames=600)
    assert not short.exists()


def test_prepare_motion_checks_checksums(tmp_path):
    bvh = tmp_path / "12_02.bvh"
    text = (CMU / "12_02.bvh").read_text()
    bvh.write_text(text.replace("Frame Time:", "Frame Time: ", 1))
    (tmp_path / "SHA256SUMS").write_text(f"{sha256_file(CMU / '12_02.bvh')}  12_02.bvh\n")
    out = tmp_path / "m.npz"
    with pytest.raises(DataFileError, match=r"12_02\.bvh: checksum mismatch"):
        prepare_motion([bvh], out, n_frames=10, checksums=tmp_path / "SHA256SUMS")
    assert not out.exists()


def test_features_round_trip_and_missing_file(tmp_path):
    rng = np.random.default_rng(0)
    fs = FeatureSet(
        rng.random((6, 4)), rng.random((6, 3)), np.arange(6), ["a", "b", "c"], {"activity": "x"}
    )
    save_features(tmp_path / "f.npz", fs)
    back = load_features(tmp_path / "f.npz")
    np.testing.assert_array_equal(back["X"], fs.X)
    np.testing.assert_array_equal(back["Y"], fs.Y)
    assert back["angle_names"] == ["a", "b", "c"] and str(back["meta"]["activity"]) == "x"
    with pytest.raises(DataFileError, match=r"gone\.npz: features file does not exist"):
        load_features(tmp_path / "gone.npz")
    with pytest.raises(DataFileError, match=r"gone\.mat: file not found"):
        load_feature_mat(tmp_path / "gone.mat")


# ------------------------------------------------------------------------------------------------ download


def _site(tmp_path):
    """A local copy of CMU's layout (SS/SS.asf, SS/SS_TT.amc) served through a file:// URL."""
    site = tmp_path / "site" / "01"
    site.mkdir(parents=True)
    shutil.copy(DATA / "01.asf", site / "01.asf")
    shutil.copy(DATA / "01_01.amc", site / "01_01.amc")
    return (tmp_path / "site").as_uri()


def test_cmu_url():
    assert (
        cmu_url("http://mocap.cs.cmu.edu/subjects", "9", "12")
        == "http://mocap.cs.cmu.edu/subjects/09/09_12.amc"
    )
    assert cmu_url("http://x/subjects/", 49) == "http://x/subjects/49/49.asf"


def test_download_from_local_url(tmp_path):
    base = _site(tmp_path)
    dest = tmp_path / "dl" / "01"
    d_asf = download_cmu_skeleton("01", dest / "01.asf", base_url=base)
    d_amc = download_cmu_trial("01", "01", dest / "01_01.amc", dest / "01.asf", base_url=base)
    assert d_amc == sha256_file(DATA / "01_01.amc") and d_asf == sha256_file(DATA / "01.asf")
    assert (dest / "01_01.amc").read_bytes() == (DATA / "01_01.amc").read_bytes()
    assert (dest / "01_01.amc.sha256").read_text().split() == [d_amc, "01_01.amc"]
    verify_checksum(dest / "01_01.amc", "sidecar")
    # With the digest known in advance, a wrong one is refused and nothing is written.
    with pytest.raises(
        DataFileError, match=r"checksum mismatch for file://.*01_01\.amc: expected sha256 f{64}"
    ):
        download_cmu_trial(
            "01",
            "01",
            tmp_path / "dl2" / "01_01.amc",
            dest / "01.asf",
            base_url=base,
            expected_sha256="f" * 64,
        )
    assert not (tmp_path / "dl2" / "01_01.amc").exists()


def test_download_that_does_not_parse_leaves_nothing(tmp_path):
    base = _site(tmp_path)
    amc = tmp_path / "site" / "01" / "01_01.amc"
    amc.write_text(amc.read_text().replace("lradius 45.0", "lradius"))
    dest = tmp_path / "dl"
    download_cmu_skeleton(1, dest / "01.asf", base_url=base)
    with pytest.raises(
        DataFileError,
        match=r"01_01\.amc: downloaded from file://.* but does not parse: .*'lradius' has 0 values",
    ):
        download_cmu_trial(1, 1, dest / "01_01.amc", dest / "01.asf", base_url=base)
    assert sorted(p.name for p in dest.iterdir()) == ["01.asf", "01.asf.sha256"]
    with pytest.raises(DataFileError, match=r"download from file://.*/02/02_01\.amc failed"):
        download_cmu_trial(2, 1, dest / "02_01.amc", dest / "01.asf", base_url=base)


# ------------------------------------------------------------------------------------ navigate (CMU 09_12, AMC)


def _datasets():
    """config/datasets.yaml as the workflow reads it (defaults filled in, paths resolved)."""
    import yaml

    from bsrbench.config import load_datasets

    return load_datasets(yaml.safe_load((ROOT / "config" / "datasets.yaml").read_text()))


def _amc_frame_numbers(path):
    """The frame-number lines of an AMC file (a line holding one whole number), counted from the text."""
    return [int(t) for t in path.read_text().split("\n") if t.strip().isdigit()]


def test_navigate_entry_loads_at_30_fps_from_the_vendored_amc(tmp_path):
    """The entry reads 09_12.amc with subject 9's ASF, verified against resources/cmu-mocap/SHA256SUMS; at one
    frame in 4 of the 1918 frames (numbered 1..1918 in the file) it keeps file frames 0, 4, ..., 1916."""
    data = _datasets()
    d = data.dataset("mocap", "navigate")
    assert d["paper_activity"] == "Navigate" and d["format"] == "amc" and d["enabled"]
    assert d["files"] == ["resources/cmu-mocap/09_12.amc"]
    assert d["asf"] == "resources/cmu-mocap/09.asf"
    numbers = _amc_frame_numbers(CMU / "09_12.amc")
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) == 1918
    params = data.motion_params("mocap", "navigate")
    out = tmp_path / "navigate.npz"
    sel = prepare_motion(
        [ROOT / f for f in d["files"]],
        out,
        asf=ROOT / d["asf"],
        **{**params, "checksums": ROOT / d["checksums"]},
    )
    expect = np.arange(0, len(numbers), 4)
    assert sel.n_frames == len(expect) == -(-len(numbers) // 4) == 480
    np.testing.assert_array_equal(sel.trial_frames, expect)
    with np.load(out) as z:
        assert list(z["trial_ids"]) == ["09_12"] and str(z["skeleton_kind"]) == "asf"
        assert z["angles"].shape == (480, 57)
        assert str(z["angle_names"][int(z["heading_column"])]) == "root_Yrotation"
        assert list(z["sha256"]) == [sha256_file(CMU / "09_12.amc")]


def test_navigate_files_are_checked_against_their_digests(tmp_path):
    """The listed digests are the files' own, and a changed byte in either file is refused by name."""
    table = {Path(p).name: h for p, h in read_checksums(CMU / "SHA256SUMS").items()}
    for name in ("09_12.amc", "09.asf"):
        assert table[name] == sha256_file(CMU / name)
        bad = tmp_path / name
        data = bytearray((CMU / name).read_bytes())
        data[-3] = ord("7") if data[-3] != ord("7") else ord("8")
        bad.write_bytes(bytes(data))
        (tmp_path / "SHA256SUMS").write_text(f"{table[name]}  {name}\n")
        with pytest.raises(DataFileError, match=rf"{name}: checksum mismatch"):
            verify_checksum(bad, tmp_path / "SHA256SUMS")


def test_navigate_is_the_trial_in_the_authors_x09_rows():
    """The vendored file is the trial the authors used: rows 398-699 of their x09.mat are 09_12 at one frame in 4
    (AMC frames 3, 7, 11, ...: their BVH conversion adds a rest frame, so its frames 4, 8, ...). Their root
    heading (third angle, Z X Y Euler order) matches the heading of our root rotation written in that order to
    a median of under a degree while the figure turns round (shifted by 4 rows, 16 frames, it does not)."""
    from scipy.spatial.transform import Rotation

    from bsrbench.mocap.asf import parse_amc, parse_asf

    amc = parse_amc(CMU / "09_12.amc", parse_asf(CMU / "09.asf"))
    assert amc.motion.shape == (1918, 62) and amc.asf.root_order[3:] == ("RX", "RY", "RZ")
    rx_ry_rz = amc.motion[3::4, 3:6][:302]
    # AMC root RX RY RZ applies x first: R = Rz Ry Rx; the authors' order Z X Y is R = Rz Rx Ry.
    ours = Rotation.from_euler("ZYX", rx_ry_rz[:, ::-1], degrees=True).as_euler("ZXY", degrees=True)
    theirs = scipy.io.loadmat(FEAT / "x09.mat")["Y"][398:700, 3:6]
    diff = (theirs[:, 2] - ours[:, 2] + 180.0) % 360.0 - 180.0
    assert np.median(np.abs(diff)) < 1.0
    shifted = (theirs[4:, 2] - ours[:-4, 2] + 180.0) % 360.0 - 180.0
    assert np.median(np.abs(shifted)) > 2.0
    assert np.ptp(np.unwrap(np.deg2rad(theirs[:, 2]))) > np.pi  # the figure turns round


# ------------------------------------------------------------------------------- AMC frames without parsing


def test_count_motion_frames_counts_the_frame_lines_of_an_amc(tmp_path):
    """An AMC's frames are its frame-number lines (one whole number on a line): the count matches what
    parse_amc and prepare_motion find, comments and keyword lines are not frames, and a missing file gives
    None as for BVH."""
    from bsrbench.datasets import motion_frame_time, motion_frames
    from bsrbench.mocap import parse_amc

    lines = (DATA / "01_01.amc").read_text().splitlines()
    text = "\n".join(["# 7", lines[0], "# frame 12"] + lines[1:]) + "\n"
    (tmp_path / "01_01.amc").write_text(text)
    shutil.copy(DATA / "01.asf", tmp_path / "01.asf")
    n = parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf").n_frames
    assert n == 3 and motion_frames(tmp_path / "01_01.amc") == n
    for skip, step in ((0, 1), (1, 1), (0, 2), (1, 2)):
        sel = prepare_motion(
            [tmp_path / "01_01.amc"],
            tmp_path / "m.npz",
            n_frames=600,
            frame_selection="first",
            skip_frames=skip,
            frame_step=step,
            fewer_frames="use_all",
        )
        assert count_motion_frames([tmp_path / "01_01.amc"], skip, step) == sel.n_frames
    # BVH and AMC trials add up; a missing AMC cannot be counted
    both = count_motion_frames([CMU / "09_01.bvh", tmp_path / "01_01.amc"], 0, 1)
    assert both == 149 + 3
    assert count_motion_frames([tmp_path / "missing.amc"], 0, 4) is None
    assert motion_frame_time(tmp_path / "01_01.amc") == pytest.approx(1 / 120)
    assert motion_frame_time(CMU / "09_01.bvh") == pytest.approx(0.00833333)


def test_navigate_is_counted_as_480_frames_before_it_is_prepared(monkeypatch):
    """The report's frame note for navigate: 1918 frame lines at one in 4 give 480 (not n_frames = 600)."""
    monkeypatch.chdir(ROOT)  # the configuration's paths are relative to the project
    data = _datasets()
    d = data.dataset("mocap", "navigate")
    numbers = _amc_frame_numbers(CMU / "09_12.amc")
    expect = len(range(int(d["skip_frames"]), len(numbers), int(d["frame_step"])))
    assert count_motion_frames(d["files"], d["skip_frames"], d["frame_step"]) == expect == 480
    assert data.data_frames("mocap", "navigate") == 480


def test_mat_rows_from_first_frame_every_frame_step(tmp_path):
    import scipy.io

    from bsrbench.datasets import count_mat_rows, load_feature_mat

    rng = np.random.default_rng(0)
    X, Y = rng.normal(size=(70, 4)), rng.uniform(-180, 180, size=(70, 6))
    path = tmp_path / "m.mat"
    scipy.io.savemat(path, {"X": X, "Y": Y})
    assert count_mat_rows(path) == 70
    late = load_feature_mat(path, n_frames=60, drop_y_columns=3, first_frame=10)
    assert np.array_equal(late.frames, np.arange(10, 70)) and np.array_equal(late.X, X[10:])
    half = load_feature_mat(
        path, n_frames=60, drop_y_columns=3, frame_step=2, fewer_frames="use_all"
    )
    assert np.array_equal(half.frames, np.arange(0, 70, 2)) and np.array_equal(half.Y, Y[::2, 3:])
    with pytest.raises(InputError, match="has 35 usable frames but n_frames = 60"):
        load_feature_mat(path, n_frames=60, drop_y_columns=3, frame_step=2)


def test_the_configuration_check_counts_a_mat_files_rows_before_any_job(tmp_path):
    """A data set whose first_frame + (n_frames - 1) x frame_step is no row of its .mat file passed the dry run and
    failed only in the features job: the check now reads the file's rows from its header and refuses it, naming
    the data set, its frame settings, the file and its rows; what fits, or what use_all keeps, passes."""
    from bsrbench.config import check_mat_rows

    path = tmp_path / "m.mat"
    scipy.io.savemat(path, {"X": np.ones((70, 4)), "Y": np.zeros((70, 6))})
    entry = dict(
        source="hsc",
        activity="late",
        format="mat",
        files=[str(path)],
        x_key="X",
        first_frame=10,
        frame_step=1,
        n_frames=60,
        frame_selection="first",
        fewer_frames="error",
    )
    check_mat_rows(entry)  # rows 10 .. 69: the last row of the file
    where = "config datasets.hsc.late (config/datasets.yaml)"
    with pytest.raises(InputError) as exc:
        check_mat_rows({**entry, "first_frame": 11})
    assert str(exc.value) == (
        f"{where}: first_frame 11, frame_step 1 and n_frames 60 need row 70, but {path} has 70 rows (X), 59 of "
        "them from first_frame every frame_step; expected first_frame + (n_frames - 1) x frame_step below 70 "
        "(lower n_frames, first_frame or frame_step, or set fewer_frames: use_all with frame_selection: first)"
    )
    with pytest.raises(
        InputError, match=r"frame_step 2 and n_frames 60 need row 128, but .* has 70 rows"
    ):
        check_mat_rows({**entry, "frame_step": 2, "frame_selection": "spread"})
    check_mat_rows({**entry, "frame_step": 2, "fewer_frames": "use_all"})  # keeps the 30 there are
    with pytest.raises(InputError) as exc:
        check_mat_rows({**entry, "first_frame": 70, "fewer_frames": "use_all"})
    assert str(exc.value) == (
        f"{where}: first_frame 70 is not a row of {path}, which has 70 rows (X); expected first_frame below 70"
    )
    check_mat_rows({**entry, "files": [str(tmp_path / "absent.mat")]})  # left to the features job
