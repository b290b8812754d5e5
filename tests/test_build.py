"""The PDF build (bsrbench.reporting.build): the page-1 header and the check of LaTeX's log."""

from bsrbench.reporting.build import build_header, config_provenance, latex_log_problems


def test_page_one_names_the_config_overrides_after_the_files():
    """Before: the header listed the configuration files only, so a study run with `--config n_train=[30,60]`
    claimed the files' N. Now the overrides follow the files, as a shell takes them (quoted where the shell
    needs it), in typewriter type with ASCII hyphens and upright quotes."""
    files = ["config/datasets.yaml", "config/config.yaml", "config/ci.yaml"]
    text = config_provenance(
        files, ["study=ci_n", "n_train=[30,60]", "report={subjective_methods: [SR]}"]
    )
    assert text.startswith(
        r"config/datasets.yaml, config/config.yaml, config/ci.yaml (in the order they apply), then "
    )
    q = r"\textquotesingle{}"
    assert text.endswith(
        r"\texttt{\frenchspacing -{}-{}config study=ci\_n "
        + q
        + "n\\_train=[30,60]"
        + q
        + " "
        + q
        + r"report=\{subjective\_methods: [SR]\}"
        + q
        + "}"
    ), text
    assert (
        config_provenance(files, [])
        == config_provenance(files)
        == ("config/datasets.yaml, config/config.yaml, config/ci.yaml (in the order they apply)")
    )
    assert (
        config_provenance([], ["job_server=False"])
        == r"none, then \texttt{\frenchspacing -{}-{}config job\_server=False}"
    )
    header = build_header(configfiles=files, overrides=["n_train=[30,60]"])
    row = [ln for ln in header.splitlines() if ln.startswith("Configuration & ")]
    assert len(row) == 1 and "n\\_train=[30,60]" in row[0]


def test_latex_log_problems_flags_overfull_boxes_and_undefined_references():
    log = "\n".join(
        [
            r"Overfull \hbox (0.5pt too wide) in paragraph at lines 3--4",
            r"Overfull \hbox (12.3pt too wide) in paragraph at lines 9--10",
            r"Overfull \vbox (3.0pt too high) has occurred while \output is active",
            r"LaTeX Warning: Reference `tab:parameters' on page 1 undefined on input line 40.",
            r"Underfull \hbox (badness 10000) in paragraph at lines 1--2",
        ]
    )
    problems = latex_log_problems(log)
    assert (
        len(problems) == 3
        and "12.3pt" in problems[0]
        and "3.0pt" in problems[1]
        and "tab:parameters" in problems[2]
    )
    assert latex_log_problems("Overfull \\hbox (0.9pt too wide)") == []
