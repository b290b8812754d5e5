"""Command-line configuration: ``snakemake --config key=value`` values read as YAML, like configuration files.

Snakemake reads a ``--config`` value with ``int``, ``float``, a boolean parser and then YAML's *BaseLoader*,
which keeps every scalar inside a list or mapping a string: ``--config n_train='[100]'`` becomes ``['100']``
and fails validation ("'100' is not of type 'integer'"). :func:`retype_cli_config` reads those list and
mapping values again with ``yaml.safe_load`` and merges them into the configuration, so that every key can be
overridden from the command line with the YAML flow syntax of the configuration files::

    snakemake --cores 2 --config n_train='[30,60]' protocols='[random,contiguous]'
    snakemake --cores 2 --config study_activities='{hsc: [golf], mocap: []}' report='{subjective_methods: [SR]}'

Mappings are merged into the configuration's, lists and scalars replace it (as with ``--configfile``).
"""

from snakemake.utils import update_config

import yaml

from .errors import InputError


def retype_cli_config(config, config_args, parsed):
    """Merge the ``--config`` list and mapping values of ``config_args`` into ``config``, read with YAML's
    safe loader (in place; returns ``config``).

    ``config_args``: the raw ``key=value`` strings (``workflow.config_settings.config_args``); ``parsed``:
    Snakemake's reading of them (``workflow.config_settings.config``). Scalars keep Snakemake's reading.
    Raises InputError naming the key when a value is not valid YAML.
    """
    if not config_args or isinstance(config_args, (str, bytes)):
        return config
    for arg in config_args:
        key, sep, text = str(arg).partition("=")
        if not sep or not isinstance(parsed.get(key), (list, dict)):
            continue
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise InputError(
                f"--config {key}: {text!r} is not valid YAML ({str(exc).splitlines()[0]}); expected e.g. "
                f"{key}='[30, 100]' or {key}='{{name: value}}'"
            ) from None
        update_config(config, {key: value})
    return config
