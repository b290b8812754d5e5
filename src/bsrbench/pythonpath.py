"""Python's path in a Snakemake run without the project's folders.

Snakemake puts the Snakefile's folder and each included rule file's folder first on ``sys.path`` (and ``python -m``
the working directory): a package planted there (``./sklearn/``, ``workflow/rules/bsrbench/``) would shadow an
installed one and run when imported. The Snakefile takes its own folder off and calls :func:`keep_project_off_path`
before it includes anything, and every rule file takes its own folder off before it imports anything (so that a
Snakefile of one's own may include them too); jobs, ``script:`` jobs and the job server run with
``PYTHONSAFEPATH=1`` (:func:`bsrbench.jobserver.configure_shell_jobs`).
"""

import os
import sys


def keep_project_off_path(basedir):
    """Remove from ``sys.path`` the folder ``basedir`` (the Snakefile's) and the working directory, everything under
    their ``workflow/`` and ``.snakemake/``, ``''`` and relative entries, unless an absolute ``PYTHONPATH`` entry
    names them (the user's explicit choice). Paths are compared resolved, so a symbolic link does not hide one."""
    here = {os.path.realpath(basedir), os.path.realpath(os.getcwd())}
    under = {
        os.path.realpath(os.path.join(d, sub)) for d in here for sub in ("workflow", ".snakemake")
    }
    kept = {
        os.path.realpath(p)
        for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
        if os.path.isabs(p)
    }

    def planted(entry):
        r = os.path.realpath(entry) if os.path.isabs(entry) else None
        if r in kept:
            return False
        return r is None or r in here or any(r == u or r.startswith(u + os.sep) for u in under)

    sys.path[:] = [p for p in sys.path if not planted(p)]
