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
    'red_black_sweep': ('body', """
v = np.array(v, dtype=float)
H, W = v.shape
deg = np.zeros((H, W))
deg[1:, :] += 1
deg[:-1, :] += 1
deg[:, 1:] += 1
deg[:, :-1] += 1
s = np.zeros((H, W))
s[1:] += v[:-1]
s[:-1] += v[1:]
s[:, 1:] += v[:, :-1]
s[:, :-1] += v[:, 1:]
return (rhs + lam * s) / (c + lam * deg)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'red_black_sweep': ('source', """def red_black_sweep(v, rhs, c, lam):
    from flowtrack.variational import red_black_sweep as ref
    return ref(v.copy(), rhs, c, lam)
"""),
    'solve_gauss_seidel': ('source', """def solve_gauss_seidel(a, b, dt, lam, tol=1e-10, max_sweeps=100000):
    import numpy as np
    from flowtrack.variational import red_black_sweep as ref, solve_component
    if tol > 0:
        return solve_component(a, b, dt, lam)
    v = np.zeros(np.shape(a))
    for _ in range(max_sweeps):
        v = ref(v, dt * (b - a), np.full(np.shape(a), dt**2), lam)
    return v
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('jacobi-not-gauss-seidel', {
        'red_black_sweep': ('body', """
v = np.array(v, dtype=float)
H, W = v.shape
deg = np.zeros((H, W))
deg[1:, :] += 1
deg[:-1, :] += 1
deg[:, 1:] += 1
deg[:, :-1] += 1
s = np.zeros((H, W))
s[1:] += v[:-1]
s[:-1] += v[1:]
s[:, 1:] += v[:, :-1]
s[:, :-1] += v[:, 1:]
return (rhs + lam * s) / (c + lam * deg)
"""),
    }),
    ('black-before-red', {
        'red_black_sweep': ('replace', 'for colour in (red, ~red):', 'for colour in (~red, red):'),
    }),
    ('neumann-boundary-degree', {
        'red_black_sweep': ('replace', 'diag = c + lam * deg', 'diag = c + lam * 4.0'),
    }),
    ('dense-solve-not-sweeps', {
        'solve_gauss_seidel': ('body', """
a = np.asarray(a, dtype=float)
H, W = a.shape
n = H * W
A = dt**2 * np.eye(n)
idx = np.arange(n).reshape(H, W)
for p, q in list(zip(idx[:, :-1].ravel(), idx[:, 1:].ravel())) + list(zip(idx[:-1].ravel(), idx[1:].ravel())):
    A[p, p] += lam
    A[q, q] += lam
    A[p, q] -= lam
    A[q, p] -= lam
return np.linalg.solve(A, (dt * (np.asarray(b) - a)).ravel()).reshape(H, W)
"""),
    }),
    ('residual-rate-not-gauss-seidel', {
        'solve_gauss_seidel': ('replace', 'v = red_black_sweep(v, rhs, c, lam)', 'v = v + 1.5 * (red_black_sweep(v, rhs, c, lam) - v)'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('red_black_sweep', 'return np.asarray(v) + 0.1'),
    ('solve_gauss_seidel', 'return (np.asarray(b) - np.asarray(a)) / dt'),
]
