"""``flowtrack ports``: the course's C++/Java/MATLAB/Mathematica/block-diagram ports and their vectors.

``vectors`` writes and checks ``cpp_java_matlab_ports/vectors/<problem>.json`` (the problems and
their cases are defined in :mod:`flowtrack_course.polyglot.problems`); ``runner`` builds and runs
every language's ports (:mod:`flowtrack_course.polyglot`) on those files, prints the table and is
the ``flowtrack ports`` command.
"""
