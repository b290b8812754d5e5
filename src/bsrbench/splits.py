"""Train/test splits of one activity's frames, and the identity of a job (:class:`JobSpec`).

Protocols: ``random`` (the paper's: N random frames train, the rest test), ``contiguous`` (one block of N
frames trains, frames farther than ``gap`` from it test, so no test frame has a near-duplicate training
neighbour), ``blocked`` (between the two: the training frames come in runs of :data:`BLOCK` consecutive frames
at random places, the test frames are those farther than ``gap`` from every run) and ``cross_trial`` (whole
trials held out as test; needs the trial of each frame).
"""

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .seeds import method_seed, split_seed

PROTOCOLS = ("random", "contiguous", "blocked", "cross_trial")
#: Length of a run of training frames of the ``blocked`` protocol (a third of a second at 30 fps).
BLOCK = 10


def make_split(n_frames, n_train, *, protocol="random", seed=0, min_test=100, gap=30, trials=None):
    """Indices ``(train, test)`` of one split, both sorted.

    ``random``: ``n_train`` frames drawn without replacement, the rest are test (the paper's protocol).
    ``contiguous``: the training frames are one block ``[s, s + n_train)`` with a random start ``s``;
    the test frames are those more than ``gap`` frames away from the block.
    ``blocked``: the frames are cut into consecutive slots of :data:`BLOCK` frames and ``ceil(n_train / BLOCK)``
    slots drawn without replacement train (the last run shortened to make ``n_train``); the test frames are
    those more than ``gap`` frames away from every training frame.
    ``cross_trial``: ``trials`` (the trial of each frame) is required; the trials are shuffled and held out
    in that order until at least ``min_test`` frames are test frames (all frames of those trials); the
    ``n_train`` training frames are drawn without replacement from the other trials' frames, so that no
    test frame has a training frame of its own trial.
    Raises InputError if fewer than ``min_test`` test frames remain (or, cross_trial, too few training frames).
    """
    n_frames, n_train, min_test, gap = int(n_frames), int(n_train), int(min_test), int(gap)
    if protocol not in PROTOCOLS:
        raise InputError(f"protocol must be one of {PROTOCOLS}; got {protocol!r}")
    if n_train < 2:
        raise InputError(f"n_train must be >= 2; got {n_train}")
    if gap < 0:
        raise InputError(f"gap must be >= 0; got {gap}")
    rng = np.random.default_rng(seed)
    if protocol == "cross_trial":
        return _cross_trial_split(n_frames, n_train, rng, min_test, trials)
    if protocol == "random":
        if n_frames - n_train < min_test:
            raise InputError(
                f"n_train={n_train} leaves {n_frames - n_train} test frames of {n_frames}; at least min_test={min_test} needed"
            )
        perm = rng.permutation(n_frames)
        return np.sort(perm[:n_train]), np.sort(perm[n_train:])
    if protocol == "blocked":
        return _blocked_split(n_frames, n_train, rng, min_test, gap)
    # contiguous: choose among starts that leave enough test frames
    starts = np.arange(0, n_frames - n_train + 1)
    n_test = n_frames - (np.minimum(starts + n_train + gap, n_frames) - np.maximum(starts - gap, 0))
    ok = starts[n_test >= min_test]
    if ok.size == 0:
        raise InputError(
            f"contiguous protocol: n_train={n_train} with gap={gap} leaves fewer than min_test={min_test} "
            f"test frames of {n_frames} for every block position"
        )
    s = int(rng.choice(ok))
    train = np.arange(s, s + n_train)
    frames = np.arange(n_frames)
    test = frames[(frames < s - gap) | (frames >= s + n_train + gap)]
    return train, test


def _blocked_split(n_frames, n_train, rng, min_test, gap):
    n_slots, n_runs = n_frames // BLOCK, -(-n_train // BLOCK)
    if n_runs > n_slots:
        raise InputError(
            f"blocked protocol: n_train={n_train} needs {n_runs} runs of {BLOCK}; {n_frames} frames hold {n_slots}"
        )
    slots = np.sort(rng.choice(n_slots, size=n_runs, replace=False))
    train = (slots[:, None] * BLOCK + np.arange(BLOCK)).ravel()[:n_train]
    near = np.zeros(n_frames, dtype=bool)
    for t in train:
        near[max(t - gap, 0) : t + gap + 1] = True
    test = np.flatnonzero(~near)
    if test.size < min_test:
        raise InputError(
            f"blocked protocol: n_train={n_train} in runs of {BLOCK} with gap={gap} leaves {test.size} test frames "
            f"of {n_frames}; at least min_test={min_test} needed"
        )
    return np.sort(train), test


def _cross_trial_split(n_frames, n_train, rng, min_test, trials):
    if trials is None:
        raise InputError(
            "protocol 'cross_trial' needs the trial of each frame (array 'trial_index' of a motion-capture "
            "features file); these features have none (use protocol 'random' or 'contiguous')"
        )
    trials = np.asarray(trials)
    if trials.shape != (n_frames,):
        raise InputError(
            f"cross_trial: trial_index has shape {trials.shape}; expected ({n_frames},)"
        )
    ids = np.unique(trials)
    if ids.size < 2:
        raise InputError(f"cross_trial: the features hold {ids.size} trial; at least 2 are needed")
    held, n_test = [], 0
    for t in rng.permutation(ids):
        if n_test >= min_test:
            break
        held.append(t)
        n_test += int(np.sum(trials == t))
    test = np.flatnonzero(np.isin(trials, held))
    pool = np.flatnonzero(~np.isin(trials, held))
    if n_test < min_test or pool.size < n_train:
        raise InputError(
            f"cross_trial: holding out trials {sorted(int(t) for t in held)} gives {n_test} test frames "
            f"(min_test={min_test}) and leaves {pool.size} frames of {ids.size - len(held)} trials for "
            f"n_train={n_train}"
        )
    return np.sort(rng.choice(pool, size=n_train, replace=False)), test


def max_n_train(n_frames, *, protocol="random", min_test=100, gap=30):
    """Largest n_train that :func:`make_split` accepts (used to check configurations before running;
    for ``cross_trial`` an upper bound, since it depends on the trial lengths)."""
    if protocol == "contiguous":
        return int(n_frames - min_test - gap)  # block at one end, gap on one side
    if (
        protocol == "blocked"
    ):  # every run far from the others: each takes BLOCK + 2 gap frames from the test
        return int((n_frames - min_test) // (BLOCK + 2 * gap)) * BLOCK
    return int(n_frames - min_test)


@dataclass
class JobSpec:
    """What identifies one job of the study."""

    source: str
    activity: str
    method: str
    n_train: int
    seed: int
    protocol: str = "random"
    pose_transform: str = "heading"
    min_test: int = 100
    gap: int = 30
    paper_activity: str = ""

    @classmethod
    def from_wildcards(cls, wildcards, params):
        """The spec of a workflow job: identity from its wildcards, settings from its params
        (``pose_transform``, ``min_test``, ``gap`` and, if present, ``paper_activity``)."""
        return cls(
            source=wildcards.source,
            activity=wildcards.activity,
            method=wildcards.method,
            n_train=int(wildcards.n_train),
            seed=int(wildcards.seed),
            protocol=wildcards.protocol,
            pose_transform=params.pose_transform,
            min_test=int(params.min_test),
            gap=int(params.gap),
            paper_activity=getattr(params, "paper_activity", "") or "",
        )

    def split(self, n_frames, trials=None):
        """``(train, test)`` of this job's split (``trials``: the trial of each frame, for cross_trial)."""
        return make_split(
            n_frames,
            self.n_train,
            protocol=self.protocol,
            seed=split_seed(self.source, self.activity, self.n_train, self.seed),
            min_test=self.min_test,
            gap=self.gap,
            trials=trials,
        )

    @property
    def method_seed(self):
        return method_seed(self.source, self.activity, self.n_train, self.seed, self.method)
