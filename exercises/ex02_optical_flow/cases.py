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
    'optical_flow': ('body', """
X = np.asarray(X, dtype=float)
Z = X[:, 2]
ux = fx * (V[:, 0] / Z - X[:, 0] * V[:, 2] / Z**2)
uy = fy * (V[:, 1] / Z - X[:, 1] * V[:, 2] / Z**2)
return np.stack([ux, uy], axis=1)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'optical_flow': ('source', """def optical_flow(X, V, dt, fx, fy):
    from flowtrack.camera import PinholeCamera, optical_flow_from_scene_flow
    return optical_flow_from_scene_flow(X, V, dt, PinholeCamera(fx, fy, 0.0, 0.0))
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('missing-dt', {
        'optical_flow': ('replace', 'axis=1) * dt', 'axis=1)'),
    }),
    ('flow-ignores-depth-motion', {
        'optical_flow': ('body', """
X = np.asarray(X, dtype=float)
V = np.asarray(V, dtype=float)
return np.stack([fx * V[:, 0] / X[:, 2], fy * V[:, 1] / X[:, 2]], axis=1) * dt
"""),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('optical_flow', 'return np.asarray(V)[:, :2] * 3.0 + 0.1'),
]
