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
    'cv_process_noise': ('body', """
q1d = q * np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])
Q = np.zeros((4, 4))
Q[:2, :2] = q1d
Q[2:, 2:] = q1d
return Q
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'cv_transition': ('source', """def cv_transition(dt):
    from flowtrack.kalman import constant_velocity_model
    return constant_velocity_model(dt, 1.0, 1.0)[0]
"""),
    'cv_process_noise': ('source', """def cv_process_noise(dt, q):
    from flowtrack.kalman import white_noise_acceleration_Q
    return white_noise_acceleration_Q(dt, q)
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('q-block-diagonal', {
        'cv_process_noise': ('body', """
q1d = q * np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])
Q = np.zeros((4, 4))
Q[:2, :2] = q1d
Q[2:, 2:] = q1d
return Q
"""),
    }),
    ('q-continuous-white-noise', {
        'cv_process_noise': ('body', """
return q * np.kron(np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]]), np.eye(2))
"""),
    }),
    ('q-missing-q', {
        'cv_process_noise': ('replace', 'q1d = q * np.array', 'q1d = np.array'),
    }),
    ('generic-transpose', {
        'cv_transition': ('replace', """    return F
""", """    return F.T
"""),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('cv_process_noise', 'return q * np.eye(4) * dt'),
]
