# Data sets: validation of config/datasets.yaml and helper functions for the mocap, features and study rules.
# Helpers only (no rules): the rules are in mocap.smk and features.smk.
import re
from pathlib import Path

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from bsrbench.cli_config import config_validation_error

from bsrbench.errors import InputError

# a schema error as one line naming the key, its value and what was expected (bsrbench.cli_config), instead of
# Snakemake's message dumping the whole schema and configuration
try:
    validate(config, "../schemas/datasets.schema.yaml")
except WorkflowError as exc:
    raise config_validation_error(exc, "data sets (config/datasets.yaml)") from None

_DATASETS_SCHEMA = yaml.safe_load(
    (Path(str(workflow.current_basedir)).parent / "schemas" / "datasets.schema.yaml").read_text()
)
#: Defaults of a data set entry, read from the schema (the schema is the one place they are written).
DATASET_DEFAULTS = {
    k: v["default"]
    for k, v in _DATASETS_SCHEMA["$defs"]["dataset"]["properties"].items()
    if "default" in v
}
MOTION_FORMATS = ("bvh", "amc")

#: The paper's eight activities (Table I: Acrobatics, Navigate, Golf; Table II: the other five).
PAPER_ACTIVITIES = [
    ("Table I", "Acrobatics"),
    ("Table I", "Navigate"),
    ("Table I", "Golf"),
    ("Table II", "Throw and catch football"),
    ("Table II", "Michael jackson styled motions"),
    ("Table II", "Kick soccer ball"),
    ("Table II", "Run"),
    ("Table II", "Walk"),
]


def download_dir():
    return config["download"]["dir"].rstrip("/")


def cmu_split(trial_id):
    """'09_12' -> ('09', '12')."""
    s, t = trial_id.split("_")
    return f"{int(s):02d}", f"{int(t):02d}"


def cmu_amc_path(trial_id):
    s, t = cmu_split(trial_id)
    return f"{download_dir()}/{s}/{s}_{t}.amc"


def cmu_asf_path(subject):
    s = f"{int(subject):02d}"
    return f"{download_dir()}/{s}/{s}.asf"


def dataset(source, activity):
    """A data set entry with the schema's defaults filled in and its input files resolved."""
    try:
        entry = config["datasets"][source][activity]
    except KeyError:
        raise InputError(
            f"config datasets: no data set {source}/{activity}; "
            f"configured: {[f'{s}/{a}' for s in config['datasets'] for a in config['datasets'][s]]}"
        ) from None
    d = {**DATASET_DEFAULTS, **entry}
    d["source"], d["activity"] = source, activity
    if d["cmu_trials"]:
        d["files"] = [cmu_amc_path(t) for t in d["cmu_trials"]]
        if d["asf"] is None:
            d["asf"] = cmu_asf_path(cmu_split(d["cmu_trials"][0])[0])
    elif d["format"] == "amc" and d["asf"] is None and d["files"]:
        f = Path(d["files"][0])
        d["asf"] = str(f.with_name(f.stem.split("_")[0] + ".asf"))
    return d


def datasets_of(source=None, enabled_only=False):
    """[(source, activity)] of the configured data sets."""
    out = []
    for s, acts in config["datasets"].items():
        if source is not None and s != source:
            continue
        for a in acts:
            if not enabled_only or dataset(s, a)["enabled"]:
                out.append((s, a))
    return out


def is_motion(source, activity):
    return dataset(source, activity)["format"] in MOTION_FORMATS


def motion_sources():
    return sorted({s for s, a in datasets_of() if is_motion(s, a)})


def mat_sources():
    return sorted({s for s, a in datasets_of() if not is_motion(s, a)})


def _alternatives(names):
    """A wildcard regex matching exactly these names (or nothing when empty)."""
    return "|".join(re.escape(n) for n in names) if names else "(?!x)x"


def motion_source_regex():
    return _alternatives(motion_sources())


def mat_source_regex():
    return _alternatives(mat_sources())


def features_path(source, activity):
    return f"results/features/{source}/{activity}.npz"


def preview_path(source, activity):
    return f"results/features/{source}/{activity}.preview.png"


def feature_targets(include_disabled=False):
    """results/features/{source}/{activity}.npz of every enabled data set (every data set if asked)."""
    return [features_path(s, a) for s, a in datasets_of(enabled_only=not include_disabled)]


def preview_targets():
    return [preview_path(s, a) for s, a in datasets_of(enabled_only=True) if is_motion(s, a)]


def motion_inputs(wildcards):
    """Inputs of the mocap pose rule: the trial files (and the ASF skeleton for amc)."""
    d = dataset(wildcards.source, wildcards.activity)
    inputs = {"trials": d["files"]}
    if d["format"] == "amc":
        inputs["asf"] = d["asf"]
    return inputs


def motion_params(wildcards):
    """Keyword arguments of bsrbench.datasets.prepare_motion for one data set."""
    d = dataset(wildcards.source, wildcards.activity)
    return {
        "n_frames": d["n_frames"],
        "frame_selection": d["frame_selection"],
        "skeleton_kind": None if d["skeleton"] == "auto" else d["skeleton"],
        "joint_map": d["joint_map"],
        "skip_frames": d["skip_frames"],
        "frame_step": d["frame_step"],
        "fewer_frames": d["fewer_frames"],
        "checksums": d["checksums"],
    }


def data_frames(source, activity):
    """Frames the data set will have: n_frames, or (motion capture with fewer_frames: use_all) what its BVH
    trials give, counted from their headers; n_frames when that cannot be counted before the files exist.
    """
    from bsrbench.datasets import count_motion_frames

    d = dataset(source, activity)
    n = int(d["n_frames"])
    if d["format"] in MOTION_FORMATS and d["fewer_frames"] == "use_all":
        have = count_motion_frames(d["files"], d["skip_frames"], d["frame_step"])
        if have is not None:
            return min(n, have)
    return n


def frame_protocol_text(source, activity):
    """How the data set's frames are chosen, as one sentence for the tables."""
    from bsrbench.datasets import bvh_header, frame_protocol

    d = dataset(source, activity)
    if d["format"] not in MOTION_FORMATS:
        return (
            f"rows of {Path(d['files'][0]).name}, first {d['n_frames']}"
            if d["frame_selection"] == "first"
            else (f"{d['n_frames']} rows of {Path(d['files'][0]).name} spread evenly")
        )
    header = bvh_header(d["files"][0])
    frame_time = header[1] if header else None
    text = frame_protocol(
        d["frame_selection"], int(d["frame_step"]), int(d["n_frames"]), frame_time
    )
    n = data_frames(source, activity)
    if n < int(d["n_frames"]):
        text += f" (the trials here give {n})"
    return text


def mat_input(wildcards):
    return dataset(wildcards.source, wildcards.activity)["files"][0]


def mat_params(wildcards):
    """Keyword arguments of bsrbench.datasets.build_mat_features for one data set."""
    d = dataset(wildcards.source, wildcards.activity)
    return {
        "n_frames": d["n_frames"],
        "frame_selection": d["frame_selection"],
        "drop_y_columns": d["drop_y_columns"],
        "x_key": d["x_key"],
        "y_key": d["y_key"],
        "checksums": d["checksums"],
        "meta": {
            "source": d["source"],
            "activity": d["activity"],
            "paper_activity": d["paper_activity"] or "",
        },
    }


def features_meta(wildcards):
    d = dataset(wildcards.source, wildcards.activity)
    return {
        "source": d["source"],
        "activity": d["activity"],
        "paper_activity": d["paper_activity"] or "",
    }


def render_params():
    """Keyword arguments of bsrbench.render.render_silhouettes from the config."""
    r = config["features"]["render"]
    return {k: r[k] for k in ("image_size", "view_azimuth_deg", "view_elevation_deg", "body_scale")}


def codebook_files():
    return list(config["features"]["codebook"]["files"])


def download_checksum(name):
    """Known SHA-256 of a downloaded file name, or None."""
    return config["download"]["checksums"].get(name)


def data_availability():
    """For each of the paper's 8 activities and each source: is the data here, and if not how to get it.

    A list of dicts: table, paper_activity, source, activity (None if the source has no entry for it), enabled,
    available (all input files present), missing (files), target (features file) and command (a snakemake
    command that downloads and builds it, or None when no rule can fetch it).
    """
    rows = []
    sources = list(config["datasets"])
    for table, pa in PAPER_ACTIVITIES:
        for s in sources:
            match = [a for a in config["datasets"][s] if dataset(s, a)["paper_activity"] == pa]
            if not match:
                rows.append(
                    {
                        "table": table,
                        "paper_activity": pa,
                        "source": s,
                        "activity": None,
                        "enabled": False,
                        "available": False,
                        "missing": [],
                        "target": None,
                        "command": None,
                    }
                )
                continue
            for a in match:
                d = dataset(s, a)
                files = list(d["files"]) + ([d["asf"]] if d["format"] == "amc" and d["asf"] else [])
                missing = [f for f in files if not Path(f).is_file()]
                downloadable = bool(d["cmu_trials"])
                rows.append(
                    {
                        "table": table,
                        "paper_activity": pa,
                        "source": s,
                        "activity": a,
                        "enabled": d["enabled"],
                        "available": not missing,
                        "missing": missing,
                        "target": features_path(s, a),
                        "command": (
                            f"snakemake --cores 1 {' '.join(missing)} && snakemake --cores 2 {features_path(s, a)}"
                            if missing and downloadable
                            else (
                                f"snakemake --cores 2 {features_path(s, a)}"
                                if not missing
                                else None
                            )
                        ),
                    }
                )
    return rows


def _check_datasets():
    """Checks the schema cannot express; errors name the key and what was expected."""
    for s, a in datasets_of():
        d = dataset(s, a)
        where = f"config datasets.{s}.{a}"
        if not d["files"]:
            raise InputError(
                f"{where}: give `files` (a list of paths) or `cmu_trials` (CMU ids 'SS_TT')"
            )
        if d["cmu_trials"] and d["format"] != "amc":
            raise InputError(
                f"{where}: cmu_trials are downloaded as .amc; expected format: amc, got {d['format']!r}"
            )
        if d["format"] == "mat" and len(d["files"]) != 1:
            raise InputError(f"{where}: format mat takes exactly one file; got {len(d['files'])}")
        for f in d["files"]:
            suffix = Path(f).suffix.lower().lstrip(".")
            if suffix != d["format"]:
                raise InputError(
                    f"{where}: file {f!r} does not end in .{d['format']} (format: {d['format']})"
                )
        if d["fewer_frames"] == "use_all" and d["frame_selection"] != "first":
            raise InputError(
                f"{where}: fewer_frames: use_all needs frame_selection: first; got {d['frame_selection']!r}"
            )
        if d["frame_step"] != 1 and d["format"] not in MOTION_FORMATS:
            raise InputError(
                f"{where}: frame_step applies to bvh/amc trials; got {d['frame_step']} for format mat"
            )
        if d["joint_map"] is not None and len(d["joint_map"]) == 0:
            raise InputError(f"{where}: joint_map is an empty list; expected joint names or null")
    both = set(motion_sources()) & set(mat_sources())
    if both:
        raise InputError(
            f"config datasets: source(s) {sorted(both)} mix format mat with bvh/amc entries; "
            f"a source holds one kind (put them under different source names)"
        )
    if any(is_motion(s, a) for s, a in datasets_of(enabled_only=True)) and not codebook_files():
        raise InputError(
            "config features.codebook.files is empty; the bvh/amc data sets need codebook trials"
        )


_check_datasets()
