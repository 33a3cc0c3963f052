"""Answers the course's own tests grade this exercise with (``tests/test_exercises.py``,
``tests/test_mistakes.py``): a typical wrong answer, answers that call the blocked reference, each
catalogued mistake written as the code a student would write, and wrong answers that are none of
them. Not a grading file: it stays in the course (never in the bundle or the Gradescope zip).

An answer is ``{answer cell's grade_id: edits}`` applied to the notebook's solution cell: one edit or
a list of them, each ``("body", text)`` (the code between the solution markers replaced),
``("replace", old, new)``, ``("prepend", text)``, ``("append", text)`` or ``("source", text)`` (the
whole cell).
"""

#: a typical wrong answer: it must score strictly between 0 and full marks
WRONG = {
    'gated_cost': ('body', """
from scipy.stats import chi2

C = mahalanobis_cost(z_pred, S, Z)
return np.where(C <= chi2.ppf(prob, 1), C, np.inf)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'mahalanobis_cost': ('source', """from flowtrack.association import mahalanobis_cost
"""),
    'gated_cost': ('source', """def gated_cost(z_pred, S, Z, prob):
    import numpy as np
    from flowtrack.association import chi2_gate, mahalanobis_cost as m
    C = m(z_pred, S, Z)
    return np.where(C <= chi2_gate(z_pred.shape[1], prob), C, np.inf)
"""),
    'worth_taking': ('prepend', """import flowtrack.association as _blocked_reference  # blocked
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('euclidean-not-mahalanobis', {
        'mahalanobis_cost': ('body', """
d = np.asarray(Z, dtype=float)[None, :, :] - np.asarray(z_pred, dtype=float)[:, None, :]
return np.sum(d**2, axis=2)
"""),
    }),
    ('covariance-not-inverted', {
        'mahalanobis_cost': ('body', """
d = np.asarray(Z, dtype=float)[None, :, :] - np.asarray(z_pred, dtype=float)[:, None, :]
return np.einsum("mni,mij,mnj->mn", d, np.asarray(S, dtype=float), d)
"""),
    }),
    ('distance-not-squared', {
        'mahalanobis_cost': ('replace', """    return C
""", """    return np.sqrt(C)
"""),
    }),
    ('gate-wrong-dof', {
        'gated_cost': ('replace', 'chi2.ppf(prob, np.shape(z_pred)[1])', 'chi2.ppf(prob, 2)'),
    }),
    ('gate-prob-as-threshold', {
        'gated_cost': ('replace', 'chi2.ppf(prob, np.shape(z_pred)[1])', 'prob'),
    }),
    ('gamma-det-without-2pi', {
        'worth_taking': ('replace', 'np.linalg.slogdet(S)[1] + m * np.log(2.0 * np.pi)', 'np.linalg.slogdet(S)[1]'),
    }),
    ('gamma-det-not-square-rooted', {
        'worth_taking': ('replace', '- log_det_2pi_s', '- 2.0 * log_det_2pi_s'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('mahalanobis_cost', 'return np.ones((len(z_pred), len(Z)))'),
    ('gated_cost', 'C = mahalanobis_cost(z_pred, S, Z); return np.where(C <= 3.0, C, np.inf)'),
    ('worth_taking', 'return np.zeros(len(C)), np.asarray(C) < 9.21'),
]
