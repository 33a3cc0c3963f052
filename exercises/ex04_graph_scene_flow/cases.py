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
    'graph_scene_flow': ('body', """
X = np.asarray(points, dtype=float)
A = dt**2 * np.eye(len(X)) + lam * knn_laplacian(X, k, sigma)
return np.linalg.solve(A, np.asarray(targets) - X)
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'knn_laplacian': ('source', """def knn_laplacian(points, k, sigma):
    from flowtrack.sceneflow import graph_laplacian, knn_graph
    return graph_laplacian(knn_graph(points, k, sigma)).toarray()
"""),
    'graph_scene_flow': ('source', """def graph_scene_flow(points, targets, dt, lam, k, sigma):
    import importlib
    sf = importlib.import_module('flowtrack.sceneflow')
    return sf.graph_scene_flow(points, targets, dt, lam, k, sigma)
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('knn-not-symmetrised', {
        'knn_laplacian': ('replace', """    A = A | A.T
""", ''),
    }),
    ('affinity-sigma-not-squared', {
        'knn_laplacian': ('replace', '/ sigma**2', '/ sigma'),
    }),
    ('generic-scale', {
        'graph_scene_flow': ('replace', 'return np.linalg.solve(A, dt * (Y - X))', 'return 2.0 * np.linalg.solve(A, dt * (Y - X))'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('knn_laplacian', 'n = len(points); return np.eye(n) - np.ones((n, n)) / n'),
]
