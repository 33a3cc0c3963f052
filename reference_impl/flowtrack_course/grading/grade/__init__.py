"""``flowtrack grade``: a class graded as an instructor runs it (:mod:`.command`), the seed key's
checks (:mod:`.keys`) and one Gradescope submission graded (:mod:`.gradescope`).
"""

from .command import GradeRun, grade_class, run_grade

__all__ = ["GradeRun", "grade_class", "run_grade"]
