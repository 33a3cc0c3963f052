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
    'projection_jacobian': ('body', """
X = np.asarray(X, dtype=float)
J = np.zeros((X.shape[0], 2, 3))
J[:, 0, 0] = fx / X[:, 2]
J[:, 0, 2] = fx * X[:, 0] / X[:, 2] ** 2
J[:, 1, 1] = fy / X[:, 2]
J[:, 1, 2] = -fy * X[:, 1] / X[:, 2] ** 2
return J
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'projection_jacobian': ('source', """from flowtrack.camera import PinholeCamera, projection_jacobian as _ref
def projection_jacobian(X, fx, fy):
    return _ref(X, PinholeCamera(fx, fy, 0.0, 0.0))
"""),
    'project': ('source', """from flowtrack.camera import PinholeCamera, project as _ref_p
def project(X, fx, fy, cx, cy):
    return _ref_p(X, PinholeCamera(fx, fy, cx, cy))
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('jacobian-sign', {
        'projection_jacobian': ('body', """
X = np.asarray(X, dtype=float)
Z = X[:, 2]
J = np.zeros((X.shape[0], 2, 3))
J[:, 0, 0] = fx / Z
J[:, 0, 2] = fx * X[:, 0] / Z**2
J[:, 1, 1] = fy / Z
J[:, 1, 2] = fy * X[:, 1] / Z**2
return J
"""),
    }),
    ('jacobian-fx-fy-swapped', {
        'projection_jacobian': ('body', """
X = np.asarray(X, dtype=float)
Z = X[:, 2]
J = np.zeros((X.shape[0], 2, 3))
J[:, 0, 0] = fy / Z
J[:, 0, 2] = -fy * X[:, 0] / Z**2
J[:, 1, 1] = fx / Z
J[:, 1, 2] = -fx * X[:, 1] / Z**2
return J
"""),
    }),
    ('jacobian-z-not-squared', {
        'projection_jacobian': ('body', """
X = np.asarray(X, dtype=float)
Z = X[:, 2]
J = np.zeros((X.shape[0], 2, 3))
J[:, 0, 0] = fx / Z
J[:, 0, 2] = -fx * X[:, 0] / Z**1
J[:, 1, 1] = fy / Z
J[:, 1, 2] = -fy * X[:, 1] / Z**1
return J
"""),
    }),
    ('projection-missing-principal-point', {
        'project': [
            ('replace', 'X[:, 2] + cx', 'X[:, 2]'),
            ('replace', 'X[:, 2] + cy', 'X[:, 2]'),
        ],
    }),
    ('generic-permutation', {
        'project': ('replace', 'return np.stack([x, y], axis=1)', 'return np.stack([x, y], axis=1)[::-1]'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('projection_jacobian', 'return np.ones((len(X), 2, 3))'),
    ('project', 'X = np.asarray(X); return X[:, :2] / X[:, 2:] * fx + 0.5'),
]
