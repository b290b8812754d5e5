"""Deterministic seeds derived from named parts (benchopt's ``get_seed`` idea), using hashlib, not hash()."""

import hashlib


def derive_seed(*parts):
    """A 32-bit seed from any sequence of str/int parts; identical across processes and platforms."""
    key = "\x1f".join(str(p) for p in parts).encode()
    return int.from_bytes(hashlib.sha256(key).digest()[:4], "little")


def split_seed(source, activity, n_train, seed):
    """Seed of the train/test split: every method sees the same split for a (source, activity, n_train, seed)."""
    return derive_seed("split", source, activity, n_train, seed)


def method_seed(source, activity, n_train, seed, method):
    """Seed of a method's own randomness (sampler, k-means init, ...)."""
    return derive_seed("method", source, activity, n_train, seed, method)
