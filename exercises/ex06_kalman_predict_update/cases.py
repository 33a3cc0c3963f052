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
    'kf_update': ('body', """
S = H @ P @ H.T
K = P @ H.T @ np.linalg.pinv(S)
x = x + K @ (z - H @ x)
P = (np.eye(len(x)) - K @ H) @ P
return x, P
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'kf_predict': ('source', """def kf_predict(x, P, F, Q):
    from flowtrack.kalman import KalmanFilter
    kf = KalmanFilter(F, [[0.0] * len(x)], Q, [[1.0]], x, P)
    kf.predict()
    return kf.x, kf.P
"""),
    'kf_update': ('source', """def kf_update(x, P, z, H, R):
    from flowtrack.kalman import KalmanFilter
    import numpy as np
    kf = KalmanFilter(np.eye(len(x)), H, np.zeros((len(x), len(x))), R, x, P)
    kf.update(z)
    return kf.x, kf.P
"""),
    'velocity_nees': ('prepend', """import flowtrack.kalman as _blocked_reference  # blocked
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('innovation-without-R', {
        'kf_update': ('replace', 'S = H @ P @ H.T + R', 'S = H @ P @ H.T'),
    }),
    ('predict-without-Q', {
        'kf_predict': ('replace', 'P = F @ P @ F.T + Q', 'P = F @ P @ F.T'),
    }),
    ('generic-sign', {
        'kf_predict': ('replace', 'x = F @ x', 'x = -(F @ x)'),
    }),
    ('nees-shared-error-left-out', {
        'velocity_nees': ('replace', 'np.asarray(C, dtype=float) + alpha**2 * np.einsum("ki,kj->kij", v, v)',
                          'np.asarray(C, dtype=float)'),
    }),
    ('nees-covariance-not-inverted', {
        'velocity_nees': ('replace', 'np.linalg.solve(Cs, e[..., None])[..., 0]', 'np.einsum("kij,kj->ki", Cs, e)'),
    }),
    ('nees-shared-error-along-the-truth', {
        'velocity_nees': ('replace', 'np.einsum("ki,kj->kij", v, v)',
                          'np.einsum("ki,kj->kij", np.asarray(v_true), np.asarray(v_true))'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('kf_update', 'return np.asarray(x) + 1.0, np.asarray(P) * 0.5'),
    ('velocity_nees', 'return np.full(len(v_meas), 3.0), 3.0'),
]
