"""What a grade run exports for other tools: the nbgrader gradebook (:mod:`.gradebook`), the LMS
gradebook files (:mod:`.lms`), ``misconceptions.csv`` and the class report (:mod:`.classreport`),
and the Gradescope autograder zip (:mod:`.gradescope`). Exports read the engine's results; they
import no command.
"""
