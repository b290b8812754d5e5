"""Error types shared by the package.

Every error raised on bad input names the file or parameter, the offending value and what was expected.
"""


class InputError(ValueError):
    """Bad input data or configuration (a file, a field, a parameter)."""


class DataFileError(InputError):
    """A data file is missing, malformed or fails its checksum. The message names the file."""

    def __init__(self, path, message):
        self.path = str(path)
        super().__init__(f"{path}: {message}")


class SamplerError(RuntimeError):
    """The MCMC sampler reached an invalid state (e.g. non-finite values)."""
