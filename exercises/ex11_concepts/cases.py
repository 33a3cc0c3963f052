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
    'q_order': ('body', """
import sympy as sp
dt, q = sp.symbols("dt q", positive=True)
G = sp.Matrix([dt**2 / 2, dt])
return str(sp.kronecker_product(q * G * G.T, sp.eye(2)))
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'q_order': ('prepend', """import flowtrack.symbolic  # blocked
"""),
    'euler_lagrange': ('prepend', """import flowtrack.symbolic  # blocked
"""),
    'inverse_depth_jacobian': ('prepend', """import flowtrack.symbolic  # blocked
"""),
    'unexcited_directions': ('prepend', """import flowtrack.symbolic  # blocked
"""),
    'nees_value': ('prepend', """import flowtrack.symbolic  # blocked
"""),
    'chosen_lambda': ('prepend', """import flowtrack.symbolic  # blocked
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('q-kron-for-this-order', {
        'q_order': ('body', "return 'Matrix([[dt**4*q/4, 0, dt**3*q/2, 0], [0, dt**4*q/4, 0, dt**3*q/2], [dt**3*q/2, 0, dt**2*q, 0], [0, dt**3*q/2, 0, dt**2*q]])'"),
    }),
    ('q-continuous-white-noise', {
        'q_order': ('body', "return 'Matrix([[dt**3*q/3, dt**2*q/2, 0, 0], [dt**2*q/2, dt*q, 0, 0], [0, 0, dt**3*q/3, dt**2*q/2], [0, 0, dt**2*q/2, dt*q]])'"),
    }),
    ('q-missing-q', {
        'q_order': ('body', "return 'Matrix([[dt**4/4, dt**3/2, 0, 0], [dt**3/2, dt**2, 0, 0], [0, 0, dt**4/4, dt**3/2], [0, 0, dt**3/2, dt**2]])'"),
    }),
    ('el-laplacian-sign', {
        'euler_lagrange': ('body', 'return "2*dt*(a + v*dt - b) + 2*lam*Lv"'),
    }),
    ('el-missing-inner-derivative', {
        'euler_lagrange': ('body', 'return "a + v*dt - b - lam*Lv"'),
    }),
    ('el-half-factor', {
        'euler_lagrange': ('body', 'return "2*dt*(a + v*dt - b) - lam*Lv"'),
    }),
    ('el-half-factor', {  # its other form: the factor 2 kept on the smoothness term only
        'euler_lagrange': ('body', 'return "dt*(a + v*dt - b) - 2*lam*Lv"'),
    }),
    ('jacobian-sign', {
        'inverse_depth_jacobian': ('body', "return 'Matrix([[f/Z, 0, f*X/Z**2], [0, f/Z, f*Y/Z**2], [0, 0, -1/Z**2]])'"),
    }),
    ('jacobian-sign', {  # in one row only
        'inverse_depth_jacobian': ('body', "return 'Matrix([[f/Z, 0, -f*X/Z**2], [0, f/Z, f*Y/Z**2], [0, 0, -1/Z**2]])'"),
    }),
    ('inverse-depth-sign', {
        'inverse_depth_jacobian': ('body', "return 'Matrix([[f/Z, 0, -f*X/Z**2], [0, f/Z, -f*Y/Z**2], [0, 0, 1/Z**2]])'"),
    }),
    ('generic-transpose', {
        'inverse_depth_jacobian': ('body', 'return "Matrix([[f/Z, 0, 0], [0, f/Z, 0], [-f*X/Z**2, -f*Y/Z**2, -1/Z**2]])"'),
    }),
    ('null-space-assumed-px-vx-order', {
        'unexcited_directions': ('body', 'return np.array([[2.0, 0.0, -dt, 0.0], [0.0, 2.0, 0.0, -dt]])'),
    }),
    ('most-excited-not-unexcited', {
        'unexcited_directions': ('body', 'return np.array([[dt / 2, 1.0, 0.0, 0.0], [0.0, 0.0, dt / 2, 1.0]])'),
    }),
    ('nees-inverted', {
        'nees_value': ('replace', 'return float(S / Pp)', 'return float(Pp / S)'),
    }),
    ('nees-assumed-consistent', {
        'nees_value': ('body', 'return 1.0'),
    }),
    ('nees-prior-covariance', {
        'nees_value': ('replace', 'return float(S / Pp)', 'return float((S + q_true) / Pm)'),
    }),
    ('lambda-largest', {
        'chosen_lambda': ('body', 'return 1.0'),
    }),
    ('lambda-smallest', {
        'chosen_lambda': ('body', 'return 0.0'),
    }),
    ('lambda-log10', {
        'chosen_lambda': ('body', 'return -2.0'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('q_order', 'return "Matrix([[q, 0, 0, 0], [0, q, 0, 0], [0, 0, q, 0], [0, 0, 0, dt]])"'),
    ('euler_lagrange', 'return "v - lam*Lv*dt"'),
    ('nees_value', 'return 2.5'),
    ('chosen_lambda', 'return 0.001'),
    ('unexcited_directions', 'return np.eye(4)[:2]'),
]
