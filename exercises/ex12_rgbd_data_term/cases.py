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
    'data_term_rows': ('body', """
X = np.asarray(X, dtype=float)
iz = 1.0 / X[:, 2]
J = np.zeros((X.shape[0], 2, 3))
J[:, 0, 0] = fx * iz
J[:, 0, 2] = -fx * X[:, 0] * iz**2
J[:, 1, 1] = fy * iz
J[:, 1, 2] = -fy * X[:, 1] * iz**2
return np.einsum("nij,ni->nj", J, grad_i), np.einsum("nij,ni->nj", J, grad_d)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'data_term_rows': ('source', """def data_term_rows(X, grad_i, grad_d, fx, fy):
    import numpy as np
    from flowtrack.camera import PinholeCamera, projection_jacobian
    J = projection_jacobian(X, PinholeCamera(fx, fy, 0.0, 0.0))
    a_d = np.einsum('nij,ni->nj', J, grad_d)
    a_d[:, 2] -= 1.0
    return np.einsum('nij,ni->nj', J, grad_i), a_d
"""),
    'pixel_normal_equations': ('source', """def pixel_normal_equations(X, grad_i, r_i, grad_d, r_d, fx, fy, w_i, w_d):
    from flowtrack.camera import PinholeCamera
    from flowtrack.rgbd_flow import pixel_normal_equations as ref
    return ref(X, grad_i, r_i, grad_d, r_d, PinholeCamera(fx, fy, 0.0, 0.0), w_i, w_d)
"""),
    'unseen_direction': ('prepend', """import flowtrack.rgbd_flow  # blocked
"""),
    'system_null_dimension': ('prepend', """import flowtrack.rgbd_flow as _blocked_reference  # blocked
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('unseen-not-normalised', {
        'unseen_direction': ('body', 'return np.cross(a_i, a_d)'),
    }),
    ('unseen-seen-direction', {
        'unseen_direction': ('body', 'return a_d / np.linalg.norm(a_d, axis=1, keepdims=True)'),
    }),
    ('null-dimension-no-smoothness', {
        'system_null_dimension': ('body', """
ev = np.linalg.eigvalsh(np.asarray(N, dtype=float))
return int(np.sum(ev <= 1e-9 * ev[:, -1:]))
"""),
    }),
    ('null-dimension-rank', {
        'system_null_dimension': ('replace', 'return int(np.sum(ev <= 1e-9 * ev[-1]))',
                                  'return int(np.sum(ev > 1e-9 * ev[-1]))'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('unseen_direction', 'return np.tile([0.0, 0.0, 1.0], (len(a_i), 1))'),
    ('system_null_dimension', 'return 1'),
]
