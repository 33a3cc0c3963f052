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
    'manage_tracks': ('body', """
tracks = {}
next_id = 0
out = []
for labels in frames:
    tracks = {lab: t for lab, t in tracks.items() if lab in labels}
    for t in tracks.values():
        t[1] += 1
        t[2] = t[2] or t[1] >= min_hits
    for lab in labels:
        if lab not in tracks:
            tracks[lab] = [next_id, 1, min_hits <= 1]
            next_id += 1
    out.append(sorted([t[0], "confirmed" if t[2] else "tentative"] for t in tracks.values()))
return out
"""),
}

#: answers that call the blocked reference: full marks in process, nothing in the sandbox
CHEAT = {
    'manage_tracks': ('source', """def manage_tracks(frames, min_hits, max_misses):
    import numpy as np
    from flowtrack.tracking import MultiObjectTracker
    trk = MultiObjectTracker(1.0, 1e-4, 1e-2, min_hits=min_hits, max_misses=max_misses)
    out = []
    for labels in frames:
        trk.step(np.array([[50.0 * l, 0.0] for l in labels]).reshape(-1, 2))
        out.append([[t.id, t.status] for t in trk.tracks])
    return out
"""),
}

#: (mistake id, answer): each mistake this exercise names, written as code
MISTAKES = [
    ('deletion-off-by-one', {
        'manage_tracks': ('replace', 't["misses"] > max_misses', 't["misses"] >= max_misses'),
    }),
    ('confirmation-off-by-one', {
        'manage_tracks': [
            ('replace', 't["hits"] >= min_hits', 't["hits"] > min_hits'),
            ('replace', '"confirmed": min_hits <= 1', '"confirmed": min_hits < 1'),
        ],
    }),
    ('tentative-track-coasts', {
        'manage_tracks': ('replace', '(t["misses"] > 0 and not t["confirmed"]) or ', ''),
    }),
    ('track-id-reused', {
        'manage_tracks': [
            ('replace', 'tracks[lab] = {"id": next_id,', 'tracks[lab] = {"id": ids.setdefault(lab, next_id),'),
            ('replace', """    next_id = 0
""", """    next_id = 0
    ids = {}
"""),
            ('replace', """                next_id += 1
""", """                next_id = max(ids.values()) + 1
"""),
        ],
    }),
]

#: (answer cell, new body): wrong answers that are none of the catalogued mistakes
UNRELATED = [
    ('manage_tracks', "return [[[0, 'confirmed']] for f in frames]"),
]
