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
    'hungarian': ('body', """
C = np.array(cost, dtype=float)
pairs = []
for _ in range(min(C.shape)):
    i, j = np.unravel_index(np.argmin(C), C.shape)
    pairs.append((i, j))
    C[i, :] = np.inf
    C[:, j] = np.inf
return np.array(pairs)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'hungarian': ('source', """def hungarian(cost):
    import numpy as np
    from scipy.optimize import linear_sum_assignment
    return np.column_stack(linear_sum_assignment(cost))
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('greedy-assignment', {
        'hungarian': ('source', """import numpy as np


def hungarian(cost):
    C = np.asarray(cost, dtype=float)
    pairs, rows, cols = [], set(), set()
    for flat in np.argsort(C, axis=None, kind="stable"):
        i, j = divmod(int(flat), C.shape[1])
        if i not in rows and j not in cols:
            rows.add(i)
            cols.add(j)
            pairs.append((i, j))
    return np.array(sorted(pairs)).reshape(-1, 2)
"""),
    }),
    ('assignment-maximises', {
        'hungarian': [
            ('replace', 'def hungarian(cost):', 'def _min_assign(cost):'),
            ('append', """

def hungarian(cost):
    return _min_assign(-np.asarray(cost, dtype=float))
"""),
        ],
    }),
    ('brute-force-assignment', {
        'hungarian': ('source', """import itertools
import numpy as np
def hungarian(cost):
    C = np.asarray(cost, dtype=float)
    T = C.shape[0] > C.shape[1]
    C = C.T if T else C
    n, m = C.shape
    best = min(itertools.permutations(range(m), n), key=lambda s: sum(C[i, s[i]] for i in range(n)))
    pairs = list(enumerate(best))
    return np.array([(j, i) for i, j in pairs] if T else pairs)
"""),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('hungarian', 'n = min(np.shape(cost)); return np.array([(i, (i + 1) % n) for i in range(n)])'),
]
