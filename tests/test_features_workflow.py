"""The data rules (download, mocap poses, codebook, features) run end to end on a tiny configuration.

Snakemake runs in a subprocess with a temporary Snakefile that includes the project's datasets, mocap and
features rule files, so the test does not depend on the study configuration.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from bsrbench.datasets import learn_codebook_from_trials, sha256_file
from bsrbench.io import load_features

ROOT = Path(__file__).resolve().parents[1]
RULES = ROOT / "workflow" / "rules"
CMU = ROOT / "resources" / "cmu-mocap"
FEAT = ROOT / "resources" / "paper-features"
DATA = Path(__file__).resolve().parent / "data"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")

SNAKEFILE = f"""\
import json
configfile: "tiny.yaml"
include: "{RULES / "datasets.smk"}"
include: "{RULES / "mocap.smk"}"
include: "{RULES / "features.smk"}"
Path("availability.json").write_text(json.dumps(data_availability()))


rule all_features:
    input:
        feature_targets(),
        preview_targets(),
"""

TINY_FRAMES = 3  # the hand-written AMC trial has 3 frames
RENDER = {
    "image_size": [40, 40],
    "view_azimuth_deg": 0.0,
    "view_elevation_deg": 0.0,
    "body_scale": None,
}


def _config(tmp, base_url):
    return {
        "datasets": {
            "hsc": {
                "golf": {
                    "paper_activity": "Golf",
                    "format": "mat",
                    "files": [str(FEAT / "x63.mat")],
                    "checksums": str(FEAT / "SHA256SUMS"),
                    "n_frames": 40,
                    "frame_selection": "first",
                },
            },
            "mocap": {
                "walk": {
                    "paper_activity": "Walk",
                    "format": "bvh",
                    "files": [str(CMU / "12_02.bvh")],
                    "checksums": str(CMU / "SHA256SUMS"),
                    "n_frames": 6,
                },
                "tiny_amc": {
                    "paper_activity": "Navigate",
                    "format": "amc",
                    "cmu_trials": ["01_01"],
                    "checksums": "sidecar",
                    "skeleton": "asf",
                    "skip_frames": 0,
                    "n_frames": TINY_FRAMES,
                },
                "not_here": {
                    "paper_activity": "Acrobatics",
                    "format": "amc",
                    "cmu_trials": ["49_21"],
                    "checksums": "sidecar",
                    "enabled": False,
                },
            },
        },
        "features": {
            "seed": 3,
            "render": RENDER,
            "shape_context": {"n_points": 24},
            "preview_frames": 4,
            "codebook": {
                "files": [str(CMU / "codebook" / "05_01.bvh"), str(CMU / "codebook" / "13_11.bvh")],
                "checksums": str(CMU / "SHA256SUMS"),
                "frames_per_trial": 4,
                "n_centres": 6,
            },
        },
        "download": {
            "base_url": base_url,
            "dir": "downloads",
            "checksums": {"01.asf": sha256_file(DATA / "01.asf")},
        },
    }


def _run(workdir, *targets):
    r = subprocess.run(
        [
            str(SNAKEMAKE),
            *targets,
            "--cores",
            "2",
            "--directory",
            str(workdir),
            "--snakefile",
            str(workdir / "Snakefile"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return r


def test_features_rules_end_to_end(tmp_path):
    site = tmp_path / "site" / "01"
    site.mkdir(parents=True)
    (site / "01.asf").write_bytes((DATA / "01.asf").read_bytes())
    (site / "01_01.amc").write_bytes((DATA / "01_01.amc").read_bytes())
    work = tmp_path / "work"
    work.mkdir()
    cfg = _config(work, (tmp_path / "site").as_uri())
    (work / "tiny.yaml").write_text(yaml.safe_dump(cfg))
    (work / "Snakefile").write_text(SNAKEFILE)

    # The amc data set's files come from the download rules (file:// here), then everything is built.
    _run(work, "all_features")

    assert (work / "downloads" / "01" / "01_01.amc.sha256").is_file()
    golf = load_features(work / "results/features/hsc/golf.npz")
    assert golf["X"].shape == (40, 100) and golf["Y"].shape == (40, 57)
    n_frames = {"walk": 6, "tiny_amc": TINY_FRAMES}
    for activity, n in n_frames.items():
        fs = load_features(work / f"results/features/mocap/{activity}.npz")
        assert fs["X"].shape == (n, 6) and fs["Y"].shape == (n, 57)
        assert np.all(fs["X"] >= 0) and np.all(fs["X"].sum(axis=1) > 0)
        assert len(fs["angle_names"]) == 57
        png = (work / f"results/features/mocap/{activity}.preview.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        motion = np.load(work / f"results/mocap/mocap/{activity}.npz")
        np.testing.assert_array_equal(motion["angles"], fs["Y"])
    assert not (work / "results/features/mocap/not_here.npz").exists()
    amc = load_features(work / "results/features/mocap/tiny_amc.npz")
    assert (
        amc["angle_names"][0] == "root_Zrotation"  # AMC roots in the authors' Z X Y order
        and str(amc["meta"]["paper_activity"]) == "Navigate"
    )
    assert list(amc["meta"]["trial_ids"]) == ["01_01"]

    # The codebook depends only on its own trials and the seed: recomputing it gives the same centres.
    with np.load(work / "results/features/codebook.npz") as z:
        centres = z["centres"]
        assert list(z["trial_ids"]) == ["05_01", "13_11"]
    again = learn_codebook_from_trials(
        cfg["features"]["codebook"]["files"],
        tmp_path / "again.npz",
        frames_per_trial=4,
        n_centres=6,
        render=RENDER,
        n_points=24,
        seed=3,
        skip_frames=6,
    )
    np.testing.assert_array_equal(again, centres)

    # The availability table: each of the paper's 8 activities for each source.
    rows = json.loads((work / "availability.json").read_text())
    assert len(rows) == 8 * 2
    by = {(r["source"], r["paper_activity"]): r for r in rows}
    assert by[("mocap", "Walk")]["available"] and by[("hsc", "Golf")]["available"]
    acro = by[("mocap", "Acrobatics")]
    assert not acro["available"] and acro["missing"] == [
        "downloads/49/49_21.amc",
        "downloads/49/49.asf",
    ]
    assert "downloads/49/49_21.amc" in acro["command"]
    assert by[("hsc", "Walk")]["activity"] is None and by[("hsc", "Walk")]["command"] is None


def test_bad_data_config_is_rejected_naming_the_key(tmp_path):
    cfg = _config(tmp_path, "file:///nowhere")
    cfg["datasets"]["hsc"]["golf"]["files"] = [str(CMU / "12_02.bvh")]
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(cfg))
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    r = subprocess.run(
        [
            str(SNAKEMAKE),
            "-n",
            "--cores",
            "1",
            "--directory",
            str(tmp_path),
            "--snakefile",
            str(tmp_path / "Snakefile"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode != 0
    out = r.stdout + r.stderr
    assert "config datasets.hsc.golf: file" in out and "does not end in .mat (format: mat)" in out
    cfg = _config(tmp_path, "file:///nowhere")
    cfg["features"]["codebook"]["n_centres"] = 1
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(cfg))
    r = subprocess.run(
        [
            str(SNAKEMAKE),
            "-n",
            "--cores",
            "1",
            "--directory",
            str(tmp_path),
            "--snakefile",
            str(tmp_path / "Snakefile"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = r.stdout + r.stderr
    assert r.returncode != 0 and "n_centres" in out and "minimum" in out
