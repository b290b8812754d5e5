# Tables, figures, generated text and the PDF report, all from {RESULTS}/aggregate/results.csv.


rule table:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        paper="resources/paper-tables.csv",
    output:
        report(
            "reports/tables/table{table}_{source}.tex",
            category="Tables",
            caption="../report/tables.rst",
        ),
    log:
        "logs/report/table{table}_{source}.log",
    params:
        methods=run_methods(),
        labels=method_labels(),
        n_train=config["n_train"],
        protocols=config["protocols"],
        status=lambda w: data_status(w.source),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/tables.py"


rule report_text:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        paper="resources/paper-tables.csv",
    output:
        findings="reports/tables/findings.tex",
        body="reports/tables/body.tex",
    log:
        "logs/report/report_text.log",
    params:
        labels=method_labels(),
        study=config["study"],
        tables=table_targets(),
        figures=figure_targets("pdf"),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/report_text.py"


rule plot_error_vs_ntrain:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        paper="resources/paper-tables.csv",
    output:
        pdf="reports/figures/error_vs_ntrain_{source}.pdf",
        png=report(
            "reports/figures/error_vs_ntrain_{source}.png",
            category="Figures",
            caption="../report/error_vs_ntrain.rst",
        ),
    log:
        "logs/report/error_vs_ntrain_{source}.log",
    params:
        methods=run_methods(),
        labels=method_labels(),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/plots_error.py"


rule plot_calibration:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
    output:
        pdf="reports/figures/calibration.pdf",
        png=report(
            "reports/figures/calibration.png",
            category="Figures",
            caption="../report/calibration.rst",
        ),
    log:
        "logs/report/calibration.log",
    params:
        methods=run_methods(),
        labels=method_labels(),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/plots_calibration.py"


rule plot_trace:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        predictions=trace_input,
    output:
        pdf="reports/figures/trace.pdf",
        png=report(
            "reports/figures/trace.png",
            category="Figures",
            caption="../report/trace.rst",
        ),
    log:
        "logs/report/trace.log",
    params:
        method=config["report"]["trace_method"],
        labels=method_labels(),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/plots_trace.py"


rule plot_subjective:
    input:
        unpack(subjective_inputs),
    output:
        pdf="reports/figures/subjective_{source}.pdf",
        png=report(
            "reports/figures/subjective_{source}.png",
            category="Figures",
            caption="../report/subjective.rst",
        ),
    log:
        "logs/report/subjective_{source}.log",
    params:
        methods=lambda w: [
            m for m in config["report"]["subjective_methods"] if m in run_methods()
        ],
        activities=lambda w: config["study_activities"][w.source],
        labels_activity=lambda w: {
            a: pa or a.replace("_", " ").capitalize()
            for a, pa in activity_labels(w.source).items()
        },
        labels=method_labels(),
        motion=subjective_motion,
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/plots_subjective.py"


rule report_pdf:
    input:
        template="reports/report.tex",
        text=rules.report_text.output,
        tables=table_targets(),
        figures=figure_targets("pdf"),
    output:
        report("reports/report.pdf", category="Report", caption="../report/report.rst"),
    log:
        "logs/report/report_pdf.log",
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    script:
        "../scripts/report_pdf.py"
