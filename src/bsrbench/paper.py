"""Facts of the paper that the study reproduces: its tables and the activities in them.

"A Bayesian Framework for Sparse Representation-Based 3D Human Pose Estimation", Tables I and II: the mean angle
error of each method on eight activities. Everything that names the paper's activities reads them from here.
"""

#: The paper's activities per table, spelled as in the paper, in its row order.
PAPER_TABLES = {
    "I": ["Acrobatics", "Navigate", "Golf"],
    "II": [
        "Throw and catch football",
        "Michael jackson styled motions",
        "Kick soccer ball",
        "Run",
        "Walk",
    ],
}
#: The paper's eight activities as (table caption, activity), in the tables' order.
PAPER_ACTIVITIES = [(f"Table {t}", a) for t, names in PAPER_TABLES.items() for a in names]
#: The columns of the paper's tables, in its order: the ``paper_name`` of the estimator classes that reproduce them
#: (:attr:`bsrbench.methods.Method.paper_name`).
PAPER_METHODS = ("RVM", "TGP", "SR", "DDL", "PM")
