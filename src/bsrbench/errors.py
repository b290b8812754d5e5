"""Error types shared by the package.

Every error raised on bad input names the file or parameter, the offending value and what was expected.
"""


class InputError(ValueError):
    """Bad input data or configuration (a file, a field, a parameter)."""


class DataFileError(InputError):
    """A data file is missing, malformed or fails its checksum. The message names the file (``path``) and, for
    a malformed text file, the line (``line``, 1-based, also written in ``message``)."""

    def __init__(self, path, message, line=None):
        self.path = str(path)
        self.line = line
        super().__init__(f"{path}: {message}")


class SamplerError(RuntimeError):
    """The MCMC sampler reached an invalid state (e.g. non-finite values)."""
