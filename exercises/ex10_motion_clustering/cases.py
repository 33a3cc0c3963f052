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
    'cluster_tracks': ('body', """
from scipy.sparse.csgraph import connected_components

P = np.asarray(points, dtype=float)
V = np.asarray(flow, dtype=float)
adj = (np.linalg.norm(P[:, None] - P[None], axis=2) <= radius) & (
    np.linalg.norm(V[:, None] - V[None], axis=2) <= sigma_v
)
K, lab = connected_components(adj, directed=False)
cents = np.array([P[lab == k].mean(axis=0) for k in range(K)])
vels = np.array([V[lab == k].mean(axis=0) for k in range(K)])
return cents, vels
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'cluster_tracks': ('source', """def cluster_tracks(points, flow, radius, sigma_v, min_speed):
    import numpy as np
    from flowtrack.clustering import cluster_motion, tracks_from_clusters
    lab = cluster_motion(points, flow, radius, sigma_v, min_speed=min_speed,
                         method='connected', k=len(points), min_size=1)
    t = tracks_from_clusters(points, flow, lab)
    return np.array([c for c, _ in t]), np.array([v for _, v in t])
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('clusters-by-position-only', {
        'cluster_tracks': ('replace', 'adj = near & alike', 'adj = near'),
    }),
    ('static-points-kept', {
        'cluster_tracks': ('replace', 'keep = np.linalg.norm(V, axis=1) >= min_speed', 'keep = np.ones(len(V), dtype=bool)'),
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('cluster_tracks', """P = np.asarray(points); V = np.asarray(flow)
return P.mean(0, keepdims=True), V.mean(0, keepdims=True)"""),
]
