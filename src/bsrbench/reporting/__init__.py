"""Tables, figures and the PDF report of the study, all computed from the aggregate result table."""
